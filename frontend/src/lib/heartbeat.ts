/**
 * The dead-man heartbeat of motion this tab started (docs/api.md issue 4): while it runs, a
 * `{"type":"heartbeat","session":sid}` goes over the WebSocket every 50 ms; the server stops
 * the axis (halt, then quick stop) when none arrived for SERVODESK_DEADMAN_MS (default
 * 250 ms). Every 50 ms leaves room for four late frames before the server gives up, and is
 * twice as often as the contract's "at least every 100 ms".
 *
 * It only sends while started: a page never heartbeats for motion it did not start, so a
 * frozen or closed tab can never keep an axis moving.
 */

export const HEARTBEAT_PERIOD_MS = 50;

export interface TimerApi {
  setInterval(fn: () => void, ms: number): unknown;
  clearInterval(handle: unknown): void;
  now(): number;
}

const browserTimers: TimerApi = {
  setInterval: (fn, ms) => globalThis.setInterval(fn, ms),
  clearInterval: (h) => globalThis.clearInterval(h as ReturnType<typeof setInterval>),
  now: () => Date.now(),
};

export interface HeartbeatInfo {
  running: boolean;
  /** Heartbeats sent since the last start. */
  sent: number;
  /** Consecutive ticks the socket could not take a heartbeat (closed). */
  missed: number;
}

export class HeartbeatLoop {
  private handle: unknown = null;
  private info: HeartbeatInfo = { running: false, sent: 0, missed: 0 };
  private readonly listeners = new Set<(i: HeartbeatInfo) => void>();

  /** `send` returns false when the heartbeat could not be sent (socket not open). */
  constructor(
    private readonly send: () => boolean,
    private readonly periodMs: number = HEARTBEAT_PERIOD_MS,
    private readonly timers: TimerApi = browserTimers,
  ) {}

  get running(): boolean {
    return this.info.running;
  }

  get state(): HeartbeatInfo {
    return this.info;
  }

  /** Start (or keep) sending; the first heartbeat goes at once. */
  start(): void {
    if (this.handle !== null) return;
    this.set({ running: true, sent: 0, missed: 0 });
    this.tick();
    this.handle = this.timers.setInterval(() => this.tick(), this.periodMs);
  }

  stop(): void {
    if (this.handle !== null) this.timers.clearInterval(this.handle);
    this.handle = null;
    if (this.info.running) this.set({ ...this.info, running: false });
  }

  onChange(listener: (i: HeartbeatInfo) => void): () => void {
    this.listeners.add(listener);
    return () => this.listeners.delete(listener);
  }

  private tick(): void {
    const ok = this.send();
    const prev = this.info;
    // Only report a change of "missed" (not every sent count) so listeners stay quiet.
    if (ok) {
      this.info = { ...prev, sent: prev.sent + 1, missed: 0 };
      if (prev.missed !== 0) this.emit();
    } else {
      this.set({ ...prev, missed: prev.missed + 1 });
    }
  }

  private set(i: HeartbeatInfo): void {
    this.info = i;
    this.emit();
  }

  private emit(): void {
    for (const l of this.listeners) l(this.info);
  }
}
