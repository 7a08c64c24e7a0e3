import { describe, expect, it } from 'vitest';
import { isStopKey, stopSummary, type StopAllItem } from './globalStop';

const key = (k: string, over: Partial<KeyboardEvent> = {}) => ({ key: k, repeat: false, ctrlKey: false, altKey: false, metaKey: false, ...over });

describe('isStopKey', () => {
  it('is Escape, alone or with Shift, once per press', () => {
    expect(isStopKey(key('Escape'))).toBe(true);
    expect(isStopKey(key('Escape', { repeat: true }))).toBe(false);
    expect(isStopKey(key('Escape', { ctrlKey: true }))).toBe(false);
    expect(isStopKey(key('Escape', { altKey: true }))).toBe(false);
    expect(isStopKey(key(' '))).toBe(false);
    expect(isStopKey(key('Enter'))).toBe(false);
  });
});

function item(session: string, result: StopAllItem['result'], message: string | null = null): StopAllItem {
  return { session, result, motion: null, message, hint: result === 'stopped' ? null : 'watch the axis' };
}

describe('stopSummary', () => {
  it('says when the user controls nothing, and where to stop such an axis', () => {
    const s = stopSummary({ user: 'local', sessions: [], stopped: 0, failed: 0, pending: 0 });
    expect(s.kind).toBe('warning');
    expect(s.title).toMatch(/control no axis/);
    expect(s.hint).toMatch(/Quick stop/);
  });
  it('lists the stopped axes', () => {
    const s = stopSummary({ user: 'local', sessions: [item('a-1', 'stopped'), item('b-2', 'stopped')], stopped: 2, failed: 0, pending: 0 });
    expect(s).toMatchObject({ kind: 'info', title: 'Stop all: 2 axes stopped' });
    expect(s.message).toContain('a-1, b-2');
  });
  it('names what failed or is not confirmed, with the reason', () => {
    const s = stopSummary({
      user: 'local',
      sessions: [item('a-1', 'stopped'), item('b-2', 'failed', 'SDO time-out'), item('c-3', 'pending', 'no answer within 2 s')],
      stopped: 1,
      failed: 1,
      pending: 1,
    });
    expect(s.kind).toBe('error');
    expect(s.title).toBe('Stop all: 2 axes of 3 not confirmed');
    expect(s.message).toContain('b-2 FAILED: SDO time-out');
    expect(s.message).toContain('c-3 not confirmed yet: no answer within 2 s');
    expect(s.hint).toBe('watch the axis');
  });
});
