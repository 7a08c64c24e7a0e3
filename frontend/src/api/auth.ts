/**
 * Who is logged in (docs/security.md "Users"): GET /auth/me at start-up, the login page when
 * it answers 401, and the rights of the role, which the UI uses to disable what the role may
 * not do (with the reason) before the server would refuse it with 403.
 *
 * The browser's credential is the session cookie the login sets (HttpOnly: this code never
 * sees it); nothing is ever taken from or put into the URL. `getToken()` stays for the
 * callers that add an Authorization header: the browser has no token, so it is always null.
 */
import { ApiError, apiRequest } from './http';
import type { components } from './schema';
import { Observable } from '../state/observable';

/** GET /auth/me; `mode` narrowed to the two the server documents (its schema says string). */
export type Me = Omit<components['schemas']['MeOut'], 'mode'> & {
  /** "single-user" (loopback, no login) or "login". */
  mode: 'single-user' | 'login';
};

/** undefined: not read yet; null: not logged in (show the login page). */
export const me = new Observable<Me | null | undefined>(undefined);

/** Why the user is on the login page again (session ended, idle time-out), or null. */
export const loginReason = new Observable<string | null>(null);

/** Remove a credential someone put into the address bar (old links had ?token=): never kept. */
export function captureTokenFromUrl(): void {
  if (typeof window === 'undefined') return;
  const url = new URL(window.location.href);
  if (!url.searchParams.has('token')) return;
  url.searchParams.delete('token');
  window.history.replaceState(window.history.state, '', url.toString());
}

export function getToken(): string | null {
  return null;
}

export async function refreshMe(): Promise<Me | null> {
  try {
    // authLost: false, since a 401 here is how the UI learns that nobody is logged in.
    const m = (await apiRequest('Read who is logged in', 'GET', '/auth/me', { authLost: false })) as Me;
    me.set(m);
    return m;
  } catch (e) {
    if (e instanceof ApiError && e.status === 401) {
      me.set(null);
      return null;
    }
    // The server did not answer: show the app, whose pages say the server is unreachable.
    const fallback: Me = { user: '?', role: '?', rights: [], mode: 'login', session: null, idle_timeout_s: 0 };
    me.set(fallback);
    return fallback;
  }
}

/** The server said 401 (or closed a socket with 4401): the login is gone. */
export function authLost(reason: string): void {
  // Also in the single-user mode: a 401 there means an account was just added (logins are
  // needed from now on).
  if (me.get() === null) return;
  loginReason.set(reason);
  void refreshMe();
}

export interface LoginFailure {
  message: string;
  hint?: string | null;
  until?: number;
}

/** Log in; on success the page reloads with the session cookie set. */
export async function login(user: string, password: string): Promise<LoginFailure | null> {
  try {
    // A wrong password is a 401 too: it is the answer here, not a lost login.
    await apiRequest('Log in', 'POST', '/auth/login', {
      body: { user, password },
      authLost: false,
      networkError: { error: 'NetworkError', message: 'the servodesk server did not answer' },
    });
  } catch (e) {
    if (!(e instanceof ApiError)) return { message: String(e) };
    // A lock-out (429) says until when (Unix time); the error schema does not list `until`.
    const until = (e.payload as { until?: unknown } | null)?.until;
    return { message: e.body.message, hint: e.body.hint ?? null, until: typeof until === 'number' ? until : undefined };
  }
  loginReason.set(null);
  return null;
}

export async function logout(): Promise<void> {
  try {
    await endSession();
  } finally {
    window.location.reload();
  }
}

/** End this login session on the server (its sockets close), without reloading the page. */
export async function endSession(): Promise<void> {
  try {
    await apiRequest('Log out', 'POST', '/auth/logout', { authLost: false });
  } catch {
    // The server is gone, or the session had ended already: its own idle time-out ends it.
  }
}

/** Whether the caller's role has `right` (everything while /auth/me is not read yet). */
export function hasRight(right: string): boolean {
  const m = me.get();
  return m === undefined || m === null ? true : m.rights.includes(right);
}

/**
 * Why the caller's role may not do something that needs `right`, or null when it may: the
 * title of a disabled button.
 */
export function rightBlocked(right: string): string | null {
  if (hasRight(right)) return null;
  const m = me.get();
  return `your role (${m?.role ?? '?'}) lacks the right "${right}"; ask an administrator`;
}
