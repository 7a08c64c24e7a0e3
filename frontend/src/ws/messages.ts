/**
 * WebSocket message shapes of /api/v1/ws (docs/api.md "WebSocket"), discriminated by `type`.
 */
import type { DriveState, SessionInfo } from '../api';
import type { HomingStatus, MotionStatus } from '../api/types';
import type { TuningJob } from '../api/tuning';

export const WS_SUBPROTOCOL = 'servodesk.v1';
/** Close code a server of another protocol version uses (docs/api.md). */
export const WS_CLOSE_VERSION = 4000;
/** Close code the server uses when the token is missing or wrong (the socket's 401). */
export const WS_CLOSE_TOKEN = 4401;

export interface HelloMessage {
  type: 'hello';
  version: string;
  protocol: number;
  /** The client id the server took for this socket (from ?client=): a label, no authority. */
  client?: string;
  /** The server's id of this connection. */
  connection?: string;
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
  event: 'lost' | 'restored' | 'closed' | 'heartbeat_lost' | 'heartbeat_restored';
  message: string | null;
}

export interface ProgressMessage {
  type: 'progress';
  session: string;
  operation: string;
  fraction: number;
  message: string | null;
}

// Operation (issue 4): control ownership, motion, dead-man, homing (docs/api.md).
export interface ControlMessage {
  type: 'control';
  session: string;
  owner: string | null;
  /** The account holding control ("local" in the single-user mode), or null. */
  user?: string | null;
  since: number | null;
  /** A WebSocket is bound to the holder's control as the dead-man. */
  bound?: boolean;
  /** The holder's socket closed: the drive was made safe; control lapses after 5 s. */
  orphaned?: boolean;
}

/** The answer to this socket's `bind`: whether it is now the dead-man of the session. */
export interface BindMessage {
  type: 'bind';
  session: string;
  ok: boolean;
  message?: string | null;
  hint?: string | null;
}

/** Sent to every socket when a drive was made safe because its holder was lost (socket
 * closed, control released or taken over): motion stopped, drive disabled. */
export interface SafeStateMessage {
  type: 'safe_state';
  session: string;
  reason: string;
  client: string | null;
  /** The drive reached Switch on disabled. */
  ok: boolean;
  /** The state it ended in (absent when reading it failed). */
  state?: string | null;
  message: string;
}

/** After a motion ended: the settings it wrote (6081h, 6083h, ...) that were put back, and
 * those that could not be (they stay marked as written since the last save). */
export interface MotionSettingsMessage {
  type: 'motion_settings';
  session: string;
  restored: string[];
  kept: string[];
}

export type MotionMessage = { type: 'motion' } & MotionStatus;

export interface DeadmanMessage {
  type: 'deadman';
  session: string;
  reason: string;
  /** The client whose motion was stopped (backend addition). */
  client?: string | null;
  latency_ms: number | null;
  detect_ms?: number | null;
  quick_stop_ms?: number | null;
  /** Set when the stop itself could not be sent. */
  message?: string | null;
}

export type HomingMessage = { type: 'homing' } & HomingStatus;

/** A tuning job's progress and end (docs/tuning.md "Service and API"). */
export interface TuningMessage {
  type: 'tuning';
  session: string;
  sid: string;
  job: TuningJob;
}

export type ServerMessage =
  | HelloMessage
  | SessionsMessage
  | StateMessage
  | EmcyMessage
  | LinkMessage
  | ProgressMessage
  | ControlMessage
  | BindMessage
  | SafeStateMessage
  | MotionSettingsMessage
  | MotionMessage
  | DeadmanMessage
  | HomingMessage
  | TuningMessage;
export type ServerMessageType = ServerMessage['type'];
export type MessageOf<T extends ServerMessageType> = Extract<ServerMessage, { type: T }>;

export type ClientMessage =
  | { type: 'subscribe'; session: string }
  | { type: 'unsubscribe'; session: string }
  | { type: 'heartbeat'; session: string }
  | { type: 'bind'; session: string; token: string };

const KNOWN: ReadonlySet<string> = new Set([
  'hello',
  'sessions',
  'state',
  'emcy',
  'link',
  'progress',
  'control',
  'bind',
  'safe_state',
  'motion_settings',
  'motion',
  'deadman',
  'homing',
  'tuning',
]);

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
