import { describe, expect, it } from 'vitest';
import { parseServerMessage } from './messages';
import { backoffDelay } from './socket';

describe('backoffDelay', () => {
  it('doubles from 0.5 s and stops at 10 s', () => {
    const mid = () => 0.5;
    expect(backoffDelay(0, mid)).toBe(500);
    expect(backoffDelay(1, mid)).toBe(1000);
    expect(backoffDelay(4, mid)).toBe(8000);
    expect(backoffDelay(5, mid)).toBe(10000);
    expect(backoffDelay(50, mid)).toBe(10000);
  });

  it('spreads reconnects by ±20 %', () => {
    expect(backoffDelay(1, () => 0)).toBe(800);
    expect(backoffDelay(1, () => 1)).toBe(1200);
  });
});

describe('parseServerMessage', () => {
  it('keeps known messages and drops the rest', () => {
    expect(parseServerMessage('{"type":"hello","version":"0.1.0","protocol":1}')?.type).toBe('hello');
    expect(parseServerMessage('{"type":"pong"}')).toBeNull();
    expect(parseServerMessage('not json')).toBeNull();
    expect(parseServerMessage('[1,2]')).toBeNull();
  });
});
