import { afterEach, beforeEach, describe, expect, it, vi } from 'vitest';
import { parseServerMessage } from './messages';
import { ServodeskSocket, backoffDelay } from './socket';

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
    expect(parseServerMessage('{"type":"pong","time":1}')?.type).toBe('pong');
    expect(parseServerMessage('{"type":"surprise"}')).toBeNull();
    expect(parseServerMessage('{"type":"toString"}')).toBeNull();
    expect(parseServerMessage('not json')).toBeNull();
    expect(parseServerMessage('[1,2]')).toBeNull();
  });
});

// A stand-in for the browser's WebSocket: records what is sent, lets the test open, answer
// and close it.
class FakeSocket {
  static readonly CONNECTING = 0;
  static readonly OPEN = 1;
  static readonly CLOSED = 3;
  static made: FakeSocket[] = [];
  readyState = FakeSocket.CONNECTING;
  sent: Array<Record<string, unknown>> = [];
  onopen: (() => void) | null = null;
  onmessage: ((ev: { data: string }) => void) | null = null;
  onclose: ((ev: { code: number; reason: string }) => void) | null = null;
  constructor(readonly url: string) {
    FakeSocket.made.push(this);
  }
  send(text: string) {
    this.sent.push(JSON.parse(text) as Record<string, unknown>);
  }
  close() {
    this.readyState = FakeSocket.CLOSED;
  }
  open() {
    this.readyState = FakeSocket.OPEN;
    this.onopen?.();
  }
  answer(msg: Record<string, unknown>) {
    this.onmessage?.({ data: JSON.stringify(msg) });
  }
  drop() {
    this.readyState = FakeSocket.CLOSED;
    this.onclose?.({ code: 1006, reason: '' });
  }
}

describe('ServodeskSocket binding (the dead-man of held control)', () => {
  beforeEach(() => {
    FakeSocket.made = [];
    vi.stubGlobal('WebSocket', FakeSocket);
    vi.useFakeTimers();
  });
  afterEach(() => {
    vi.useRealTimers();
    vi.unstubAllGlobals();
  });

  it('binds every held session when it connects and keeps the answers', () => {
    const held = { token: 'tok', sessions: ['a', 'b'] };
    const s = new ServodeskSocket(() => 'ws://x/api/v1/ws', () => held);
    const seen: Array<[string, string]> = [];
    s.onBind((sid, b) => seen.push([sid, b.state]));
    s.start();
    const ws = FakeSocket.made[0]!;
    expect(s.bindStatus('a').state).toBe('unbound');
    ws.open();
    expect(ws.sent).toEqual([
      { type: 'bind', session: 'a', token: 'tok' },
      { type: 'bind', session: 'b', token: 'tok' },
    ]);
    expect(s.bindStatus('a').state).toBe('pending');
    ws.answer({ type: 'bind', session: 'a', ok: true });
    ws.answer({ type: 'bind', session: 'b', ok: false, message: 'nobody holds control of b', hint: 'take control first' });
    expect(s.bindStatus('a')).toEqual({ state: 'bound', message: null, hint: null });
    expect(s.bindStatus('b')).toEqual({ state: 'refused', message: 'nobody holds control of b', hint: 'take control first' });
    expect(seen).toContainEqual(['a', 'bound']);
    s.stop();
  });

  it('loses its bindings when the socket closes and binds again after the reconnect', () => {
    let held: { token: string; sessions: string[] } | null = null;
    const s = new ServodeskSocket(() => 'ws://x/api/v1/ws', () => held);
    s.start();
    const first = FakeSocket.made[0]!;
    first.open();
    expect(first.sent).toEqual([]);
    // Take control: the page binds at once.
    held = { token: 'tok', sessions: ['a'] };
    expect(s.bind('a', 'tok')).toBe(true);
    first.answer({ type: 'bind', session: 'a', ok: true });
    expect(s.bindStatus('a').state).toBe('bound');
    first.drop();
    expect(s.bindStatus('a').state).toBe('unbound');
    expect(s.bindStatus('a').message).toContain('closed');
    vi.advanceTimersByTime(2_000);
    const second = FakeSocket.made[1]!;
    second.open();
    expect(second.sent).toContainEqual({ type: 'bind', session: 'a', token: 'tok' });
    second.answer({ type: 'bind', session: 'a', ok: true });
    expect(s.bindStatus('a').state).toBe('bound');
    // Released: the binding is gone with the control.
    s.unbind('a');
    expect(s.bindStatus('a').state).toBe('unbound');
    s.stop();
  });

  it('says why a bind could not be sent while the socket is down', () => {
    const s = new ServodeskSocket(() => 'ws://x/api/v1/ws', () => null);
    expect(s.bind('a', 'tok')).toBe(false);
    expect(s.bindStatus('a').state).toBe('unbound');
    expect(s.bindStatus('a').message).toContain('not connected');
  });
});

describe('parseServerMessage (control messages)', () => {
  it('keeps bind and safe_state', () => {
    expect(parseServerMessage('{"type":"bind","session":"a","ok":true}')?.type).toBe('bind');
    expect(parseServerMessage('{"type":"safe_state","session":"a","reason":"r","client":"c","ok":true,"message":"m"}')?.type).toBe('safe_state');
  });
});
