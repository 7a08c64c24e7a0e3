/**
 * Accounts, login sessions and API tokens (docs/api.md "Users and sessions"). Listing and
 * changing accounts and sessions needs the manage_users right; one's own API tokens only read.
 */
import { API_BASE, ApiError, normaliseErrorBody } from './client';

export interface Account {
  name: string;
  role: string;
  disabled: boolean;
  created: number;
}

export interface LoginSession {
  id: string;
  user: string;
  address: string;
  created: number;
  last_seen: number;
  websockets: number;
}

export interface ApiTokenInfo {
  id: string;
  user: string;
  label: string;
  created: number;
  last_used: number | null;
}

export interface ApiTokenCreated extends ApiTokenInfo {
  /** Shown once: the server keeps only its hash. */
  secret: string;
}

export const ROLES = ['administrator', 'engineer', 'service', 'operator', 'guest'] as const;

async function call<T>(action: string, method: string, path: string, body?: unknown): Promise<T> {
  const headers: Record<string, string> = { Accept: 'application/json' };
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  let res: Response;
  try {
    res = await fetch(API_BASE + path, { method, headers, body: body === undefined ? null : JSON.stringify(body) });
  } catch {
    throw new ApiError(action, 0, { error: 'NetworkError', message: 'the servodesk server did not answer' });
  }
  if (res.status === 204) return undefined as T;
  const text = await res.text();
  let payload: unknown = text;
  try {
    payload = text ? JSON.parse(text) : null;
  } catch {
    // Keep the text.
  }
  if (!res.ok) throw new ApiError(action, res.status, normaliseErrorBody(res.status, res.statusText, payload));
  return payload as T;
}

export const usersApi = {
  list: () => call<Account[]>('List accounts', 'GET', '/auth/users'),
  create: (name: string, role: string, password: string) =>
    call<Account>(`Add ${name}`, 'POST', '/auth/users', { name, role, password }),
  update: (name: string, patch: { role?: string; disabled?: boolean; password?: string }) =>
    call<Account>(`Change ${name}`, 'PATCH', `/auth/users/${encodeURIComponent(name)}`, patch),
  remove: (name: string) => call<void>(`Remove ${name}`, 'DELETE', `/auth/users/${encodeURIComponent(name)}`),
  sessions: () => call<LoginSession[]>('List sessions', 'GET', '/auth/sessions'),
  endSession: (id: string) => call<void>('End session', 'DELETE', `/auth/sessions/${encodeURIComponent(id)}`),
  tokens: () => call<ApiTokenInfo[]>('List API tokens', 'GET', '/auth/tokens'),
  createToken: (label: string) => call<ApiTokenCreated>('Make an API token', 'POST', '/auth/tokens', { label }),
  deleteToken: (id: string) => call<void>('Delete API token', 'DELETE', `/auth/tokens/${encodeURIComponent(id)}`),
};
