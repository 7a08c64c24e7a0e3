/**
 * Typed REST client for /api/v1 (docs/api.md).
 *
 * Every failure becomes an {@link ApiError} that carries the server's error body, so the UI
 * can say what failed, why (message, protocol code and its meaning) and what to do (hint)
 * instead of showing JSON.
 */
import { getToken } from './auth';
import type {
  ApiErrorBody,
  DriveState,
  Health,
  ObjectValue,
  ObjectWrite,
  ProfileSummary,
  ScanRequest,
  ScanResult,
  SessionInfo,
  SessionRequest,
  StateCommand,
} from './index';

export const API_BASE = '/api/v1';

export class ApiError extends Error {
  readonly status: number;
  readonly body: ApiErrorBody;
  /** What the user was doing, e.g. "Write 0x6041:00". */
  readonly action: string;

  constructor(action: string, status: number, body: ApiErrorBody) {
    super(body.message);
    this.name = 'ApiError';
    this.action = action;
    this.status = status;
    this.body = body;
  }
}

/** Turn any error body the server may send into the documented shape. */
export function normaliseErrorBody(status: number, statusText: string, payload: unknown): ApiErrorBody {
  if (payload !== null && typeof payload === 'object') {
    const p = payload as Record<string, unknown>;
    if (typeof p.message === 'string') {
      return {
        error: typeof p.error === 'string' ? p.error : `HTTP ${status}`,
        message: p.message,
        hint: typeof p.hint === 'string' ? p.hint : null,
        field: typeof p.field === 'string' ? p.field : null,
        code: typeof p.code === 'number' ? p.code : null,
        code_hex: typeof p.code_hex === 'string' ? p.code_hex : null,
        meaning: typeof p.meaning === 'string' ? p.meaning : null,
        protocol: typeof p.protocol === 'string' ? p.protocol : null,
        address: typeof p.address === 'string' ? p.address : null,
      };
    }
    // FastAPI's default shape ({"detail": ...}); the contract says the server maps it, but a
    // person should still read a sentence if it slips through.
    const detail = p.detail;
    if (typeof detail === 'string') return { error: `HTTP ${status}`, message: detail };
    if (Array.isArray(detail)) {
      const parts = detail.map((d: unknown) => {
        if (d && typeof d === 'object') {
          const e = d as { loc?: unknown; msg?: unknown };
          const loc = Array.isArray(e.loc) ? e.loc.filter((x) => x !== 'body').join('.') : '';
          const msg = typeof e.msg === 'string' ? e.msg : 'invalid';
          return loc ? `${loc}: ${msg}` : msg;
        }
        return String(d);
      });
      return { error: `HTTP ${status}`, message: parts.join('; ') };
    }
  }
  const text = typeof payload === 'string' && payload.trim() && payload.length < 300 ? payload.trim() : '';
  return {
    error: `HTTP ${status}`,
    message: text || `the server answered ${status} ${statusText}`.trim(),
    hint: status === 401 ? 'open the page with ?token=<token> as printed by servodesk serve' : null,
  };
}

async function request<T>(action: string, method: string, path: string, body?: unknown): Promise<T> {
  const headers: Record<string, string> = { Accept: 'application/json' };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  let res: Response;
  try {
    res = await fetch(API_BASE + path, {
      method,
      headers,
      body: body === undefined ? null : JSON.stringify(body),
    });
  } catch {
    throw new ApiError(action, 0, {
      error: 'NetworkError',
      message: 'the servodesk server did not answer',
      hint: 'check that "servodesk serve" is still running and reachable from this browser',
    });
  }
  if (res.status === 204) return undefined as T;
  const text = await res.text();
  let payload: unknown = text;
  try {
    payload = text ? JSON.parse(text) : null;
  } catch {
    // Keep the text; normaliseErrorBody shows it if it is short.
  }
  if (!res.ok) throw new ApiError(action, res.status, normaliseErrorBody(res.status, res.statusText, payload));
  return payload as T;
}

const seg = encodeURIComponent;

export const api = {
  health: () => request<Health>('Check the server', 'GET', '/health'),
  profiles: () => request<ProfileSummary[]>('Load the drive profiles', 'GET', '/profiles'),
  scan: (req: ScanRequest) => request<ScanResult>('Scan the bus', 'POST', '/bus/scan', req),
  sessions: () => request<SessionInfo[]>('List the sessions', 'GET', '/sessions'),
  openSession: (req: SessionRequest) =>
    request<SessionInfo>(`Open node ${req.node_id} on ${req.interface}`, 'POST', '/sessions', req),
  session: (sid: string) => request<SessionInfo>(`Load session ${sid}`, 'GET', `/sessions/${seg(sid)}`),
  closeSession: (sid: string) => request<void>(`Close session ${sid}`, 'DELETE', `/sessions/${seg(sid)}`),
  readObject: (sid: string, addr: string) =>
    request<ObjectValue>(`Read ${addr}`, 'GET', `/sessions/${seg(sid)}/objects/${seg(addr)}`),
  writeObject: (sid: string, addr: string, body: ObjectWrite) =>
    request<ObjectValue>(`Write ${addr}`, 'PUT', `/sessions/${seg(sid)}/objects/${seg(addr)}`, body),
  state: (sid: string) => request<DriveState>('Read the drive state', 'GET', `/sessions/${seg(sid)}/state`),
  command: (sid: string, command: StateCommand, label: string) =>
    request<DriveState>(label, 'POST', `/sessions/${seg(sid)}/state`, { command }),
};
