import { describe, expect, it } from 'vitest';
import { HEARTBEAT_PERIOD_MS, HeartbeatLoop, type TimerApi } from './heartbeat';

/** Timers driven by hand: advance(ms) fires every interval that is due. */
function fakeTimers() {
  let now = 0;
  let next = 1;
  const intervals = new Map<number, { fn: () => void; ms: number; due: number }>();
  const api: TimerApi = {
    setInterval: (fn, ms) => {
      const id = next++;
      intervals.set(id, { fn, ms, due: now + ms });
      return id;
    },
    clearInterval: (h) => {
      intervals.delete(h as number);
    },
    now: () => now,
  };
  function advance(ms: number) {
    const end = now + ms;
    for (;;) {
      let first: [number, { fn: () => void; ms: number; due: number }] | null = null;
      for (const e of intervals) if (e[1].due <= end && (!first || e[1].due < first[1].due)) first = e;
      if (!first) break;
      now = first[1].due;
      first[1].due += first[1].ms;
      first[1].fn();
    }
    now = end;
  }
  return { api, advance, count: () => intervals.size };
}

describe('HeartbeatLoop', () => {
  it('sends at once and then every 50 ms, so the 250 ms dead-man never fires while it runs', () => {
    const t = fakeTimers();
    const sent: number[] = [];
    const loop = new HeartbeatLoop(() => (sent.push(t.api.now()), true), HEARTBEAT_PERIOD_MS, t.api);
    loop.start();
    t.advance(1000);
    expect(sent[0]).toBe(0);
    expect(sent).toHaveLength(21);
    const gaps = sent.slice(1).map((x, i) => x - (sent[i] ?? 0));
    expect(Math.max(...gaps)).toBeLessThanOrEqual(100);
    expect(loop.state.sent).toBe(21);
  });

  it('stops sending when stopped, and start is idempotent (one timer)', () => {
    const t = fakeTimers();
    let n = 0;
    const loop = new HeartbeatLoop(() => (n++, true), 50, t.api);
    loop.start();
    loop.start();
    expect(t.count()).toBe(1);
    t.advance(100);
    loop.stop();
    const before = n;
    t.advance(1000);
    expect(n).toBe(before);
    expect(loop.running).toBe(false);
    expect(t.count()).toBe(0);
  });

  it('counts heartbeats the closed socket could not take, and reports it', () => {
    const t = fakeTimers();
    let open = false;
    const seen: number[] = [];
    const loop = new HeartbeatLoop(() => open, 50, t.api);
    loop.onChange((i) => seen.push(i.missed));
    loop.start();
    t.advance(100);
    expect(loop.state.missed).toBe(3);
    open = true;
    t.advance(50);
    expect(loop.state.missed).toBe(0);
    expect(seen).toContain(3);
    expect(seen[seen.length - 1]).toBe(0);
  });
});
