/**
 * Accounts, login sessions and API tokens (docs/api.md "Users and sessions"). Listing and
 * changing accounts and sessions needs the manage_users right; one's own API tokens only read.
 * Endpoint functions on the one fetch wrapper (`./http`), typed from the schema.
 */
import { apiRequest } from './http';
import type { components } from './schema';

type S = components['schemas'];

export type Account = S['UserOut'];
export type LoginSession = S['LoginSessionOut'];
export type ApiTokenInfo = S['TokenOut'];
/** `secret` is shown once: the server keeps only its hash. */
export type ApiTokenCreated = S['TokenCreated'];
export type Role = S['Role'];

export const ROLES = [
  'administrator',
  'engineer',
  'service',
  'operator',
  'guest',
] as const satisfies readonly Role[];

export const usersApi = {
  list: () => apiRequest('List accounts', 'GET', '/auth/users'),
  // A role comes from a <select> of ROLES as text; the server refuses any other (422).
  create: (name: string, role: string, password: string) =>
    apiRequest(`Add ${name}`, 'POST', '/auth/users', { body: { name, role: role as Role, password } }),
  update: (name: string, patch: { role?: string; disabled?: boolean; password?: string }) =>
    apiRequest(`Change ${name}`, 'PATCH', '/auth/users/{name}', {
      params: { name },
      body: { ...patch, role: patch.role as Role | undefined },
    }),
  remove: (name: string) => apiRequest(`Remove ${name}`, 'DELETE', '/auth/users/{name}', { params: { name } }),
  sessions: () => apiRequest('List sessions', 'GET', '/auth/sessions'),
  endSession: (session_id: string) =>
    apiRequest('End session', 'DELETE', '/auth/sessions/{session_id}', { params: { session_id } }),
  tokens: () => apiRequest('List API tokens', 'GET', '/auth/tokens'),
  createToken: (label: string) => apiRequest('Make an API token', 'POST', '/auth/tokens', { body: { label } }),
  deleteToken: (token_id: string) =>
    apiRequest('Delete API token', 'DELETE', '/auth/tokens/{token_id}', { params: { token_id } }),
};
