import { describe, expect, it } from 'vitest';
import { capturePeriod, channelsText, noteProblem, periodText, reasonProblem, titleProblem, unitText } from './kept';

describe('kept captures: what the Keep form refuses', () => {
  it('needs a title that is not blank, as the server does', () => {
    expect(titleProblem('')).toMatch(/title/);
    expect(titleProblem('   ')).toMatch(/title/);
    expect(titleProblem('ripple at 300 rpm')).toBeNull();
    expect(titleProblem('x'.repeat(201))).toMatch(/201 characters.*200/);
    expect(titleProblem('a\0b')).toMatch(/NUL/);
  });
  it('takes any note up to 4000 characters, and a deletion only with a reason', () => {
    expect(noteProblem('')).toBeNull();
    expect(noteProblem('x'.repeat(4001))).toMatch(/4000/);
    expect(reasonProblem(' ')).toMatch(/audit log/);
    expect(reasonProblem('wrong axis')).toBeNull();
  });
});

describe('kept captures: how the list says channels, units and periods', () => {
  const pos = { name: 'Position actual value', unit: 'rev', raw_unit: 'inc', scale: 1 / 131072, period_s: 0.001 };
  const vel = { name: 'Velocity actual value', unit: '', raw_unit: 'inc/s', scale: 1, period_s: 0.0101 };
  it('names each channel with its engineering unit, else its raw one', () => {
    expect(channelsText([pos, vel])).toBe('Position actual value [rev], Velocity actual value [inc/s]');
    expect(unitText(pos)).toBe('rev (raw inc, × 7.629e-6)');
    expect(unitText({ unit: 'inc/s', raw_unit: 'inc/s', scale: 1 })).toBe('inc/s');
  });
  it('gives the sample period with its rate, or the range when channels differ', () => {
    expect(periodText(0.001)).toBe('1 ms (1 kHz)');
    expect(periodText(null)).toBe('—');
    expect(capturePeriod([pos, { period_s: 0.001 }])).toBe('1 ms (1 kHz)');
    expect(capturePeriod([pos, vel])).toBe('1 ms … 10.1 ms');
    expect(capturePeriod([{ period_s: null }])).toBe('—');
  });
});
