import { describe, expect, it } from 'vitest';
import { dcpNicFromNote, hex4, nameProblem } from './dcp';

describe('nameProblem', () => {
  it('accepts the names PROFINET allows', () => {
    for (const n of ['axis-1', 'lecsn-t.line2.plant-a', '', 'x'.repeat(63), 'port-1x2']) {
      expect(nameProblem(n)).toBeNull();
    }
  });
  it('says which rule a name breaks', () => {
    expect(nameProblem('Axis-1')).toBe('lower case only');
    expect(nameProblem('axis_1')).toContain('"axis_1"');
    expect(nameProblem('-axis')).toContain("no '-' at either end");
    expect(nameProblem('a..b')).toContain('""');
    expect(nameProblem('x'.repeat(64))).toContain('1-63');
    expect(nameProblem('port-001')).toBe('port-xyz names are reserved');
    expect(nameProblem('192.168.0.1')).toBe('an IP address is not a name');
  });
});

describe('dcpNicFromNote', () => {
  it("finds the twin's interface in its session's note", () => {
    expect(dcpNicFromNote('LECSN-T twin. DCP: search network interface sddcp123x1m.')).toBe('sddcp123x1m');
    expect(dcpNicFromNote('no DCP here')).toBeNull();
    expect(dcpNicFromNote(null)).toBeNull();
  });
});

describe('hex4', () => {
  it('writes IDs as the GSDML does', () => {
    expect(hex4(0x010c)).toBe('010Ch');
    expect(hex4(null)).toBe('—');
  });
});
