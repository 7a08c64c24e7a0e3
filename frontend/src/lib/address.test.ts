import { describe, expect, it } from 'vitest';
import { formatAddress, parseAddress } from './address';

function parsed(text: string): string {
  const r = parseAddress(text);
  if (!r.ok) throw new Error(r.message);
  return formatAddress(r.address);
}

describe('parseAddress', () => {
  it('reads the spellings manuals use', () => {
    expect(parsed('0x6040')).toBe('0x6040:00');
    expect(parsed('0x6040:00')).toBe('0x6040:00');
    expect(parsed('6040h.0')).toBe('0x6040:00');
    expect(parsed('6040h.1')).toBe('0x6040:01');
    expect(parsed('1018:4')).toBe('0x1018:04');
    expect(parsed(' 0x1A00:0x10 ')).toBe('0x1A00:10');
    expect(parsed('6041')).toBe('0x6041:00');
  });

  it('reads PROFIdrive parameter numbers as decimal indices', () => {
    expect(parsed('P24640')).toBe('0x6040:00');
    expect(parsed('p24640.1')).toBe('0x6040:01');
    expect(parsed('P4112[1]')).toBe('0x1010:01');
  });

  it('refuses what is not an address, with a hint', () => {
    const r = parseAddress('0x6040:100');
    expect(r.ok).toBe(false);
    const empty = parseAddress('');
    expect(empty.ok).toBe(false);
    if (!empty.ok) {
      expect(empty.message).toContain('empty');
      expect(empty.hint).toContain('0x6040:00');
    }
    expect(parseAddress('hello').ok).toBe(false);
    expect(parseAddress('P70000').ok).toBe(false);
    expect(parseAddress('0x16040').ok).toBe(false);
  });
});
