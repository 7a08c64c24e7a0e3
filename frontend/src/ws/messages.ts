/**
 * WebSocket message shapes of /api/v1/ws (docs/api.md "WebSocket"), discriminated by `type`.
 */
import type { components } from '../api/schema';

export const WS_SUBPROTOCOL = 'servodesk.v1';
/** Close code a server of another protocol version uses (docs/api.md). */
export const WS_CLOSE_VERSION = 4000;
/** Close code the server uses when the token is missing or wrong (the socket's 401). */
export const WS_CLOSE_TOKEN = 4401;

type S = components['schemas'];

// The messages are generated from the backend's ServerMessage / ClientMessage
// (backend/servodesk/api/ws_messages.py -> openapi.json -> ../api/schema.ts; docs/architecture.md
// "Wire contract"): only the names the UI imports are aliased here.
export type HelloMessage = S['HelloMessage'];
export type StateMessage = S['StateMessage'];
export type LinkMessage = S['LinkMessage'];
export type ControlMessage = S['ControlMessage'];
export type BindMessage = S['BindMessage'];
export type SafeStateMessage = S['SafeStateMessage'];
export type MotionSettingsMessage = S['MotionSettingsMessage'];
export type DeadmanMessage = S['DeadmanMessage'];

/** A tuning job's progress and end (docs/tuning.md "Service and API"); its `job` is the one
 * GET /sessions/{sid}/tuning answers. */
export type TuningMessage = S['TuningMessage'];

export type ServerMessage = S['ServerMessage'];
export type ServerMessageType = ServerMessage['type'];
export type MessageOf<T extends ServerMessageType> = Extract<ServerMessage, { type: T }>;

export type ClientMessage = S['ClientMessage'];

/** Every type the server sends: a type added to the backend's union does not compile until
 * it is added here too. */
const KNOWN: Readonly<Record<ServerMessageType, true>> = {
  hello: true,
  sessions: true,
  state: true,
  emcy: true,
  nmt: true,
  link: true,
  progress: true,
  control: true,
  protection: true,
  bind: true,
  safe_state: true,
  motion_settings: true,
  motion: true,
  deadman: true,
  homing: true,
  tuning: true,
  pdo: true,
  pong: true,
  error: true,
};

function known(type: string): type is ServerMessageType {
  return Object.hasOwn(KNOWN, type);
}

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
  if (typeof type !== 'string' || !known(type)) return null;
  return data as ServerMessage;
}
