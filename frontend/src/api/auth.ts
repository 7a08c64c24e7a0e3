/**
 * Who is logged in (docs/security.md "Users"): GET /auth/me at start-up, the login page when
 * it answers 401, and the rights of the role, which the UI uses to disable what the role may
 * not do (with the reason) before the server would refuse it with 403.
 *
 * The browser's credential is the session cookie the login sets (HttpOnly: this code never
 * sees it); nothing is ever taken from or put into the URL. `getToken()` stays for the
 * callers that add an Authorization header: the browser has no token, so it is always null.
 */
import { Observable } from '../state/observable';

export interface Me {
  user: string;
  role: string;
  rights: string[];
  /** "single-user" (loopback, no login) or "login". */
  mode: 'single-user' | 'login';
  session: string | null;
  idle_timeout_s: number;
}

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
    const res = await fetch('/api/v1/auth/me', { headers: { Accept: 'application/json' } });
    if (res.status === 401) {
      me.set(null);
      return null;
    }
    if (!res.ok) throw new Error(`HTTP ${res.status}`);
    const m = (await res.json()) as Me;
    me.set(m);
    return m;
  } catch {
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
  let res: Response;
  try {
    res = await fetch('/api/v1/auth/login', {
      method: 'POST',
      headers: { 'Content-Type': 'application/json', Accept: 'application/json' },
      body: JSON.stringify({ user, password }),
    });
  } catch {
    return { message: 'the servodesk server did not answer' };
  }
  if (res.ok) {
    loginReason.set(null);
    return null;
  }
  try {
    const body = (await res.json()) as { message?: string; hint?: string | null; until?: number };
    return { message: body.message ?? `HTTP ${res.status}`, hint: body.hint ?? null, until: body.until };
  } catch {
    return { message: `HTTP ${res.status}` };
  }
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
    await fetch('/api/v1/auth/logout', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: '{}' });
  } catch {
    // The server is gone: its own idle time-out ends the session.
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
