/**
 * WebSocket message shapes of /api/v1/ws (docs/api.md "WebSocket"), discriminated by `type`.
 */
import type { DriveState, SessionInfo } from '../api';

export const WS_SUBPROTOCOL = 'servodesk.v1';
/** Close code a server of another protocol version uses (docs/api.md). */
export const WS_CLOSE_VERSION = 4000;
/** Close code the server uses when the token is missing or wrong (the socket's 401). */
export const WS_CLOSE_TOKEN = 4401;

export interface HelloMessage {
  type: 'hello';
  version: string;
  protocol: number;
}

export interface SessionsMessage {
  type: 'sessions';
  sessions: SessionInfo[];
}

export type StateMessage = { type: 'state'; session: string } & DriveState;

export interface EmcyMessage {
  type: 'emcy';
  session: string;
  code: number;
  code_hex: string;
  register: number;
  name: string;
  cause: string | null;
  remedy: string | null;
  time: number;
}

export interface LinkMessage {
  type: 'link';
  session: string;
  event: 'lost' | 'restored' | 'closed';
  message: string | null;
}

export type ServerMessage = HelloMessage | SessionsMessage | StateMessage | EmcyMessage | LinkMessage;
export type ServerMessageType = ServerMessage['type'];
export type MessageOf<T extends ServerMessageType> = Extract<ServerMessage, { type: T }>;

export type ClientMessage =
  | { type: 'subscribe'; session: string }
  | { type: 'unsubscribe'; session: string };

const KNOWN: ReadonlySet<string> = new Set(['hello', 'sessions', 'state', 'emcy', 'link']);

/** Parse one text frame; null for anything that is not a known message. */
export function parseServerMessage(text: string): ServerMessage | null {
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch {
    return null;
  }
  if (!data || typeof data !== 'object') return null;
  const type = (data as { type?: unknown }).type;
  if (typeof type !== 'string' || !KNOWN.has(type)) return null;
  return data as ServerMessage;
}
