/**
 * The API token (docs/api.md "REST and WebSocket API"): taken from `?token=` on the first
 * page load, kept in sessionStorage for the tab, and removed from the address bar so it does
 * not end up in bookmarks or screenshots.
 */

const KEY = 'servodesk.token';

function storage(): Storage | null {
  try {
    return typeof sessionStorage === 'undefined' ? null : sessionStorage;
  } catch {
    // Storage can be disabled by the browser's privacy settings; the token then lives in memory.
    return null;
  }
}

let memoryToken: string | null = null;

/** Read a token from the page URL once, store it, and strip it from the address bar. */
export function captureTokenFromUrl(): void {
  if (typeof window === 'undefined') return;
  const url = new URL(window.location.href);
  const token = url.searchParams.get('token');
  if (token === null) return;
  setToken(token);
  url.searchParams.delete('token');
  window.history.replaceState(window.history.state, '', url.toString());
}

export function setToken(token: string | null): void {
  memoryToken = token;
  const s = storage();
  if (!s) return;
  if (token === null) s.removeItem(KEY);
  else s.setItem(KEY, token);
}

export function getToken(): string | null {
  return storage()?.getItem(KEY) ?? memoryToken;
}
