import { describe, expect, it } from 'vitest';
import { idleExpired, lockReason } from './idleLock';

describe('idle lock', () => {
  it('locks when the time-out has passed since the last input, not before', () => {
    expect(idleExpired(0, 899_999, 900)).toBe(false);
    expect(idleExpired(0, 900_000, 900)).toBe(true);
  });
  it('never locks with a time-out of 0', () => {
    expect(idleExpired(0, 1e12, 0)).toBe(false);
  });
  it('says why in minutes or seconds', () => {
    expect(lockReason(900)).toContain('15 min');
    expect(lockReason(3)).toContain('3 s');
  });
});
