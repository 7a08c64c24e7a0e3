/**
 * The scope's binary WebSocket (`/api/v1/scope/ws`, subprotocol servodesk.scope.v1,
 * docs/scope.md "Streaming rules"): frames go into the model as they arrive (appending in
 * place, no drawing here), status frames to the page; it reconnects like the shared socket.
 *
 * The socket carries no client id: the server ties control and the dead-man to that id, and
 * the scope closing must not look like the control owner leaving.
 */
import { type ScopeStatus, type ScopeStatusFrame, scopeSocketUrl } from '../../api/scope';
import { backoffDelay } from '../../ws/socket';
import type { ScopeModel } from './model';
import { KIND_CAPTURE, KIND_STATUS, SUBPROTOCOL, decodeFrame } from '../../scope/wire';

export interface StreamEvents {
  status: (s: ScopeStatus) => void;
  /** A capture frame arrived (the model shows it already). */
  capture: () => void;
  connected: (open: boolean) => void;
  /** A frame that could not be read (the message says why). */
  error: (message: string) => void;
}

/** A status frame's JSON body (ScopeStatusFrame in openapi.json), or null when it is not one:
 * the socket's bytes are checked for the fields the page reads before they are trusted. */
export function statusOf(body: unknown): ScopeStatusFrame | null {
  if (!body || typeof body !== 'object') return null;
  const o = body as Record<string, unknown>;
  if (o.type !== 'status' || typeof o.state !== 'string' || !Array.isArray(o.channels)) return null;
  return o as unknown as ScopeStatusFrame;
}

export function openScopeStream(model: ScopeModel, on: StreamEvents, url: () => string = scopeSocketUrl): () => void {
  let ws: WebSocket | null = null;
  let stopped = false;
  let attempt = 0;
  let timer: ReturnType<typeof setTimeout> | null = null;

  const connect = () => {
    let sock: WebSocket;
    try {
      sock = new WebSocket(url(), SUBPROTOCOL);
    } catch {
      retry();
      return;
    }
    sock.binaryType = 'arraybuffer';
    ws = sock;
    sock.onopen = () => {
      attempt = 0;
      // A new connection numbers its frames from the start.
      model.lastSeq = null;
      on.connected(true);
    };
    sock.onmessage = (ev: MessageEvent) => {
      if (!(ev.data instanceof ArrayBuffer)) {
        // A text message: a status as JSON (the server may send either form).
        if (typeof ev.data === 'string') {
          try {
            const st = statusOf(JSON.parse(ev.data));
            if (st) on.status(st);
          } catch {
            // Not JSON: nothing the scope reads.
          }
        }
        return;
      }
      let frame;
      try {
        frame = decodeFrame(ev.data);
      } catch (e) {
        on.error(e instanceof Error ? e.message : String(e));
        return;
      }
      if (frame.kind === KIND_STATUS) {
        model.noteFrame(frame);
        const st = statusOf(frame.status);
        if (st) on.status(st);
        return;
      }
      model.ingest(frame);
      if (frame.kind === KIND_CAPTURE) on.capture();
    };
    sock.onclose = () => {
      if (ws !== sock) return;
      ws = null;
      on.connected(false);
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
  return () => {
    stopped = true;
    if (timer) clearTimeout(timer);
    const s = ws;
    ws = null;
    if (s && s.readyState <= WebSocket.OPEN) s.close(1000, 'page closed');
  };
}
