/**
 * Progress of a long operation (save to EEPROM takes up to ~25 s on the LECSN, manual
 * §20.9.1) from the WebSocket's `progress` messages (docs/api.md).
 *
 * The shared socket (ws/socket.ts) drops message types it does not know, and `progress` is
 * not among them yet, so this opens a short-lived socket of its own for the operation,
 * subscribed to the one session. Once ws/messages.ts knows `progress`, this can become
 * `socket.on('progress', ...)` with no change to its callers.
 */
import type { components } from '../api/schema';
import { defaultSocketUrl } from './socket';
import { WS_SUBPROTOCOL } from './messages';

/** The `progress` message, generated from the backend's (api/ws_messages.py). */
export type ProgressMessage = components['schemas']['ProgressMessage'];

export function parseProgress(text: string): ProgressMessage | null {
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch {
    return null;
  }
  if (!data || typeof data !== 'object') return null;
  const m = data as Record<string, unknown>;
  if (m.type !== 'progress' || typeof m.session !== 'string' || typeof m.fraction !== 'number') return null;
  return {
    type: 'progress',
    session: m.session,
    operation: typeof m.operation === 'string' ? m.operation : '',
    fraction: Math.max(0, Math.min(1, m.fraction)),
    message: typeof m.message === 'string' ? m.message : null,
  };
}

export interface ProgressWatch {
  /** Resolves when the socket is subscribed (or failed: progress is a nicety, not a must). */
  ready: Promise<void>;
  close: () => void;
}

/**
 * The socket URL for a progress watcher: without the tab's `client` id, because the server
 * ties control and the dead-man to that id, and a watcher's socket closing must not look
 * like the control owner's.
 */
export function progressSocketUrl(): string {
  const url = new URL(defaultSocketUrl());
  url.searchParams.delete('client');
  return url.toString();
}

/**
 * Watch the messages of `operation` on session `sid` that `parse` accepts, on a short-lived
 * socket of its own; call close() when the operation is over.
 */
export function watchMessages<M extends { session: string; operation: string }>(
  sid: string,
  operation: string,
  parse: (text: string) => M | null,
  onMessage: (m: M) => void,
  url: () => string = progressSocketUrl,
): ProgressWatch {
  let ws: WebSocket | null = null;
  let resolveReady: () => void = () => undefined;
  const ready = new Promise<void>((r) => {
    resolveReady = r;
  });
  // Do not hold the operation up for long if the socket cannot connect.
  const giveUp = setTimeout(() => resolveReady(), 1500);
  try {
    ws = new WebSocket(url(), WS_SUBPROTOCOL);
    ws.onopen = () => {
      ws?.send(JSON.stringify({ type: 'subscribe', session: sid }));
      // The subscribe is processed in order before any later publish; a short pause lets the
      // server register it before the operation starts.
      setTimeout(() => resolveReady(), 50);
    };
    ws.onmessage = (ev: MessageEvent) => {
      if (typeof ev.data !== 'string') return;
      const m = parse(ev.data);
      if (m && m.session === sid && (!m.operation || m.operation === operation)) onMessage(m);
    };
    ws.onerror = () => resolveReady();
    ws.onclose = () => resolveReady();
  } catch {
    resolveReady();
  }
  return {
    ready,
    close: () => {
      clearTimeout(giveUp);
      resolveReady();
      if (ws && ws.readyState <= WebSocket.OPEN) ws.close(1000, 'operation done');
      ws = null;
    },
  };
}

/** Watch `operation` progress of session `sid`; call close() when the operation is over. */
export function watchProgress(
  sid: string,
  operation: string,
  onProgress: (m: ProgressMessage) => void,
  url: () => string = progressSocketUrl,
): ProgressWatch {
  return watchMessages(sid, operation, parseProgress, onProgress, url);
}
