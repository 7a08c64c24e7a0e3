import { describe, expect, it } from 'vitest';
import { dcCycleProblem, syncText } from './sync';

const HIWIN = [250_000, 4_000_000, 250_000];

describe('dcCycleProblem', () => {
  it('takes the cycles of the profile', () => {
    expect(dcCycleProblem(1, HIWIN)).toBeNull();
    expect(dcCycleProblem(1.25, HIWIN)).toBeNull();
    expect(dcCycleProblem(4, HIWIN)).toBeNull();
  });
  it('names the rule for one it does not take', () => {
    expect(dcCycleProblem(1.1, HIWIN)).toBe('SYNC0 takes 0.25 ms steps from 0.25 ms to 4 ms');
    expect(dcCycleProblem(5, HIWIN)).toMatch(/to 4 ms/);
    expect(dcCycleProblem(1, null)).toBe('the drive names no SYNC0 cycle');
  });
});

describe('syncText', () => {
  it('says which clock drives the exchange', () => {
    expect(syncText('dc', 1)).toBe('DC SYNC0 every 1 ms');
    expect(syncText('freerun', 10)).toBe('SYNC every 10 ms');
    expect(syncText(null, null)).toBeNull();
  });
});
