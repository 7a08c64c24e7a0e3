/**
 * One typed WebSocket to /api/v1/ws for the whole UI.
 *
 * It speaks subprotocol "servodesk.v1", reconnects with exponential backoff (0.5 s doubling
 * to 10 s, with jitter so many tabs do not reconnect in step), and re-sends the
 * subscriptions after every reconnect so pages do not have to. A close with code 4000 means
 * the server speaks another protocol version: reconnecting would not help, so it stops and
 * reports why.
 *
 * The socket is the dead-man of the drives this tab holds control of (docs/api.md "Control
 * and motion as built"): after every (re)connect it binds each session the tab holds with the
 * tab's control token (`{"type":"bind","session","token"}`), and right after a take
 * (`bind()`); the server's answer is kept per session (`bindStatus`, `onBind`). Only a bound
 * socket's heartbeats count, and servo on and motion need one.
 */
import { authLost, getToken } from '../api/auth';
import { tabClientId } from '../lib/backupClientId';
import { type HeldControl, tabControl } from '../lib/controlToken';
import {
  type ClientMessage,
  type MessageOf,
  type ServerMessageType,
  WS_CLOSE_TOKEN,
  WS_CLOSE_VERSION,
  WS_SUBPROTOCOL,
  parseServerMessage,
} from './messages';

export type SocketStatus = 'connecting' | 'open' | 'closed' | 'incompatible';

export interface SocketStatusInfo {
  status: SocketStatus;
  /** Why the socket is not open (close reason or code), for the header tooltip. */
  detail: string | null;
  /** Seconds until the next reconnect attempt, when closed. */
  retryIn: number | null;
}

type Handler<T extends ServerMessageType> = (msg: MessageOf<T>) => void;

/** This socket's binding to a session's control: none, asked, confirmed, or refused. */
export type BindState = 'unbound' | 'pending' | 'bound' | 'refused';

export interface BindStatus {
  state: BindState;
  /** Why it is not bound (the server's refusal, or the socket being down). */
  message: string | null;
  hint: string | null;
}

export const UNBOUND: BindStatus = { state: 'unbound', message: null, hint: null };

export function backoffDelay(attempt: number, random: () => number = Math.random): number {
  const base = Math.min(10_000, 500 * 2 ** Math.max(0, attempt));
  return Math.round(base * (0.8 + 0.4 * random()));
}

export function defaultSocketUrl(): string {
  const proto = window.location.protocol === 'https:' ? 'wss:' : 'ws:';
  const url = new URL(`${proto}//${window.location.host}/api/v1/ws`);
  const token = getToken();
  if (token) url.searchParams.set('token', token);
  // The server ties control and the dead-man heartbeat to this id (docs/api.md issue 4).
  url.searchParams.set('client', tabClientId());
  return url.toString();
}

export class ServodeskSocket {
  private ws: WebSocket | null = null;
  private attempt = 0;
  private timer: ReturnType<typeof setTimeout> | null = null;
  private stopped = false;
  private readonly subscriptions = new Map<string, number>();
  private readonly handlers = new Map<ServerMessageType, Set<(msg: never) => void>>();
  private readonly statusListeners = new Set<(s: SocketStatusInfo) => void>();
  private statusInfo: SocketStatusInfo = { status: 'closed', detail: null, retryIn: null };
  private readonly binds = new Map<string, BindStatus>();
  private readonly bindListeners = new Set<(session: string, status: BindStatus) => void>();

  constructor(
    private readonly url: () => string = defaultSocketUrl,
    /** What this tab holds control of: bound again after every (re)connect. */
    private readonly held: () => HeldControl | null = () => tabControl.snapshot(),
  ) {}

  get status(): SocketStatusInfo {
    return this.statusInfo;
  }

  start(): void {
    this.stopped = false;
    if (!this.ws) this.connect();
  }

  stop(): void {
    this.stopped = true;
    if (this.timer) clearTimeout(this.timer);
    this.timer = null;
    this.ws?.close(1000, 'page closed');
    this.ws = null;
    this.dropBinds('the WebSocket is closed');
    this.setStatus({ status: 'closed', detail: 'stopped', retryIn: null });
  }

  on<T extends ServerMessageType>(type: T, handler: Handler<T>): () => void {
    let set = this.handlers.get(type);
    if (!set) {
      set = new Set();
      this.handlers.set(type, set);
    }
    const h = handler as (msg: never) => void;
    set.add(h);
    return () => set?.delete(h);
  }

  onStatus(listener: (s: SocketStatusInfo) => void): () => void {
    this.statusListeners.add(listener);
    listener(this.statusInfo);
    return () => this.statusListeners.delete(listener);
  }

  /** Subscribe to a session's live state; returns the matching unsubscribe. Reference-counted. */
  subscribe(session: string): () => void {
    const n = this.subscriptions.get(session) ?? 0;
    this.subscriptions.set(session, n + 1);
    if (n === 0) this.send({ type: 'subscribe', session });
    let done = false;
    return () => {
      if (done) return;
      done = true;
      const left = (this.subscriptions.get(session) ?? 1) - 1;
      if (left <= 0) {
        this.subscriptions.delete(session);
        this.send({ type: 'unsubscribe', session });
      } else {
        this.subscriptions.set(session, left);
      }
    };
  }

  /** Dead-man heartbeat for motion this tab started; false when the socket is not open. */
  heartbeat(session: string): boolean {
    return this.send({ type: 'heartbeat', session });
  }

  /**
   * Make this socket the dead-man of `session` (this tab holds its control with `token`).
   * False when the socket is not open: it binds every held session when it connects.
   */
  bind(session: string, token: string): boolean {
    if (!this.send({ type: 'bind', session, token })) {
      this.setBind(session, { state: 'unbound', message: 'the WebSocket is not connected: it binds when it connects', hint: null });
      return false;
    }
    this.setBind(session, { state: 'pending', message: null, hint: null });
    return true;
  }

  /** Control of `session` was released or lost: the server dropped the binding with it. */
  unbind(session: string): void {
    if (this.binds.has(session)) this.setBind(session, UNBOUND);
  }

  bindStatus(session: string): BindStatus {
    return this.binds.get(session) ?? UNBOUND;
  }

  /** Called with every change of a session's binding; returns the unsubscribe. */
  onBind(listener: (session: string, status: BindStatus) => void): () => void {
    this.bindListeners.add(listener);
    return () => this.bindListeners.delete(listener);
  }

  private setBind(session: string, status: BindStatus): void {
    this.binds.set(session, status);
    for (const l of this.bindListeners) l(session, status);
  }

  /** The socket closed: no binding survives it (the server made those drives safe). */
  private dropBinds(why: string): void {
    for (const [session, b] of this.binds) {
      if (b.state !== 'unbound' || b.message !== why) this.setBind(session, { state: 'unbound', message: why, hint: null });
    }
  }

  private bindHeld(): void {
    const held = this.held();
    if (!held) return;
    for (const session of held.sessions) this.bind(session, held.token);
  }

  private send(msg: ClientMessage): boolean {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    this.ws.send(JSON.stringify(msg));
    return true;
  }

  private setStatus(s: SocketStatusInfo): void {
    this.statusInfo = s;
    for (const l of this.statusListeners) l(s);
  }

  private connect(): void {
    this.setStatus({ status: 'connecting', detail: null, retryIn: null });
    let ws: WebSocket;
    try {
      ws = new WebSocket(this.url(), WS_SUBPROTOCOL);
    } catch (e) {
      this.scheduleReconnect(e instanceof Error ? e.message : 'cannot open the WebSocket');
      return;
    }
    this.ws = ws;
    ws.onopen = () => {
      this.attempt = 0;
      this.setStatus({ status: 'open', detail: null, retryIn: null });
      for (const session of this.subscriptions.keys()) this.send({ type: 'subscribe', session });
      // Control outlives a reconnect (and a reload) by the server's grace: bind again now.
      this.bindHeld();
    };
    ws.onmessage = (ev: MessageEvent) => {
      if (typeof ev.data !== 'string') return;
      const msg = parseServerMessage(ev.data);
      if (!msg) return;
      if (msg.type === 'bind') {
        this.setBind(msg.session, msg.ok ? { state: 'bound', message: null, hint: null } : { state: 'refused', message: msg.message ?? 'the server refused the binding', hint: msg.hint ?? null });
      }
      const set = this.handlers.get(msg.type);
      if (!set) return;
      for (const h of set) {
        try {
          (h as (m: typeof msg) => void)(msg);
        } catch (err) {
          // One broken page must not stop the others from getting updates.
          console.error('servodesk: WebSocket handler failed', err);
        }
      }
    };
    ws.onclose = (ev: CloseEvent) => {
      if (this.ws !== ws) return;
      this.ws = null;
      this.dropBinds('the WebSocket is closed: the drive was made safe; it binds again when it reconnects');
      if (this.stopped) return;
      if (ev.code === WS_CLOSE_VERSION) {
        this.setStatus({
          status: 'incompatible',
          detail: ev.reason || 'the server speaks another protocol version; reload the page',
          retryIn: null,
        });
        return;
      }
      if (ev.code === WS_CLOSE_TOKEN) {
        // The login session ended (logout, idle time-out, an administrator): log in again.
        authLost(ev.reason || 'your session ended: log in again');
        this.scheduleReconnect(ev.reason || 'log in again');
        return;
      }
      this.scheduleReconnect(ev.reason || (ev.code === 1006 ? 'connection lost' : `closed (${ev.code})`));
    };
  }

  private scheduleReconnect(detail: string): void {
    const delay = backoffDelay(this.attempt);
    this.attempt += 1;
    this.setStatus({ status: 'closed', detail, retryIn: Math.ceil(delay / 1000) });
    this.timer = setTimeout(() => {
      this.timer = null;
      if (!this.stopped) this.connect();
    }, delay);
  }
}
