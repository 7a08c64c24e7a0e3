/**
 * Hash routing: `#/<page>` for global pages and `#/<page>/<session id>` for per-drive pages.
 * The hash keeps every page a plain load of `/`, so the backend needs no SPA fallback and a
 * link to one drive's page can be bookmarked.
 */
import { Observable, useObservable } from './observable';

export interface Route {
  page: string;
  sid: string | null;
}

export function parseHash(hash: string): Route {
  const parts = hash.replace(/^#\/?/, '').split('/').filter(Boolean);
  const page = parts[0] ?? '';
  const sid = parts[1] !== undefined ? decodeURIComponent(parts[1]) : null;
  return { page, sid };
}

export function routeHref(page: string, sid?: string | null): string {
  return sid ? `#/${page}/${encodeURIComponent(sid)}` : `#/${page}`;
}

/** `#/<page>/<session id>/<part>`: a part of a per-drive page, e.g. a parameter group. */
export function partHref(page: string, sid: string, part: string): string {
  return part ? `${routeHref(page, sid)}/${encodeURIComponent(part)}` : routeHref(page, sid);
}

/** The part a hash names after the session id (null: none). */
export function hashPart(hash: string): string | null {
  const third = hash.replace(/^#\/?/, '').split('/').filter(Boolean)[2];
  return third !== undefined ? decodeURIComponent(third) : null;
}

const route = new Observable<Route>(
  typeof window === 'undefined' ? { page: '', sid: null } : parseHash(window.location.hash),
);

if (typeof window !== 'undefined') {
  window.addEventListener('hashchange', () => {
    const next = parseHash(window.location.hash);
    const cur = route.get();
    if (cur.page !== next.page || cur.sid !== next.sid) route.set(next);
  });
}

export function navigate(page: string, sid?: string | null): void {
  window.location.hash = routeHref(page, sid);
}

export function useRoute(): Route {
  return useObservable(route);
}

/** The drive the per-drive pages show when the URL names none: the last one looked at. */
export const currentSession = new Observable<string | null>(null);
