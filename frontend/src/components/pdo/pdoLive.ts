/**
 * Live cyclic data of one session from the WebSocket's `pdo` messages (docs/pdo.md
 * "WebSocket": the latest values keyed by address, and the rate of each PDO, at up to 20 Hz
 * while cyclic data runs).
 *
 * The PDO page keeps a socket of its own while it is open (the shared one, ws/socket.ts,
 * follows the sessions other pages subscribe to), subscribed to the one session and
 * reconnecting like the shared one. It connects without the tab's client id:
 * the server ties control and the dead-man to that id, and this socket closing must not look
 * like the control owner leaving.
 */
import type { components } from '../../api/schema';
import type { PdoLiveValue } from '../../api/types';
import { Observable } from '../../state/observable';
import { WS_SUBPROTOCOL } from '../../ws/messages';
import { progressSocketUrl } from '../../ws/progress';
import { backoffDelay } from '../../ws/socket';

/** The `pdo` message, generated from the backend's (api/ws_messages.py). */
export type PdoMessage = components['schemas']['PdoMessage'];

export interface PdoLive {
  values: Record<string, PdoLiveValue>;
  rates: Record<string, number>;
  /** When the last message came (ms since epoch, browser clock), null before the first. */
  received: number | null;
  /** Messages received since the socket opened. */
  count: number;
  connected: boolean;
}

export const EMPTY_LIVE: PdoLive = { values: {}, rates: {}, received: null, count: 0, connected: false };

/** One text frame as a `pdo` message, or null when it is anything else. */
export function parsePdoMessage(text: string): PdoMessage | null {
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch {
    return null;
  }
  if (!data || typeof data !== 'object') return null;
  const m = data as Partial<PdoMessage>;
  if (m.type !== 'pdo' || typeof m.session !== 'string') return null;
  // The keys as liveKey() makes them, so that a page's lookup finds them whatever their case.
  const values: PdoMessage['values'] = {};
  for (const [k, v] of Object.entries(m.values ?? {})) if (v && typeof v === 'object') values[liveKey(k)] = v;
  return { type: 'pdo', session: m.session, link: m.link ?? null, values, rates: m.rates ?? {}, time: m.time ?? 0 };
}

/** The canonical key of an address as the live values are stored ("0x606C:00"). */
export function liveKey(address: string): string {
  return address.toUpperCase().replace(/^0X/, '0x');
}

/** Watch session `sid`'s cyclic data until stop() is called. */
export function watchPdoLive(sid: string, url: () => string = progressSocketUrl): { live: Observable<PdoLive>; stop: () => void } {
  const live = new Observable<PdoLive>(EMPTY_LIVE);
  let ws: WebSocket | null = null;
  let stopped = false;
  let attempt = 0;
  let timer: ReturnType<typeof setTimeout> | null = null;

  const connect = () => {
    let sock: WebSocket;
    try {
      sock = new WebSocket(url(), WS_SUBPROTOCOL);
    } catch {
      retry();
      return;
    }
    ws = sock;
    sock.onopen = () => {
      attempt = 0;
      sock.send(JSON.stringify({ type: 'subscribe', session: sid }));
      live.update((v) => ({ ...v, connected: true, count: 0 }));
    };
    sock.onmessage = (ev: MessageEvent) => {
      if (typeof ev.data !== 'string' || !ev.data.includes('"pdo"')) return;
      const m = parsePdoMessage(ev.data);
      if (!m || m.session !== sid) return;
      // A message carries the latest values; one that leaves some out does not clear them.
      live.update((v) => ({ values: { ...v.values, ...m.values }, rates: m.rates, received: Date.now(), count: v.count + 1, connected: true }));
    };
    sock.onclose = () => {
      if (ws !== sock) return;
      ws = null;
      live.update((v) => ({ ...v, connected: false }));
      retry();
    };
  };

  const retry = () => {
    if (stopped) return;
    timer = setTimeout(() => {
      timer = null;
      if (!stopped) connect();
    }, backoffDelay(attempt++));
  };

  connect();
  return {
    live,
    stop: () => {
      stopped = true;
      if (timer) clearTimeout(timer);
      const s = ws;
      ws = null;
      if (s && s.readyState <= WebSocket.OPEN) s.close(1000, 'page closed');
    },
  };
}
