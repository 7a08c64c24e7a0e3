/**
 * This tab's control token (docs/api.md "Control and motion as built").
 *
 * Taking control of a session answers a token; every request that changes a drive carries it
 * as `X-Servodesk-Control`, and the tab's WebSocket binds itself with it as the drive's
 * dead-man. One token serves every session the tab holds: taking control of another session
 * sends the token the tab has, and the server answers the same one. The token and the
 * sessions it holds live in sessionStorage, which lasts exactly as long as the tab: a reload
 * keeps them (and binds again within the server's 5 s grace, keeping control), another tab
 * has its own. Releasing (or losing) the last session clears the token.
 */
import type { IdStorage } from './backupClientId';

/** What the token needs of sessionStorage (a plain object in tests). */
export interface TokenStorage extends IdStorage {
  removeItem?(key: string): void;
}

export const CONTROL_KEY = 'servodesk.control';
export const CONTROL_HEADER = 'X-Servodesk-Control';

/** What the tab holds: the token and the sessions it is the holder of. */
export interface HeldControl {
  token: string;
  sessions: readonly string[];
}

/** The server's header pattern (api/control_deps.py): URL-safe base64, at most 64. */
export function isValidToken(token: unknown): token is string {
  return typeof token === 'string' && /^[A-Za-z0-9_-]{1,64}$/.test(token);
}

/** The stored value, or null for anything that is not a usable one. */
export function parseHeld(text: string | null): HeldControl | null {
  if (!text) return null;
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch {
    return null;
  }
  if (!data || typeof data !== 'object') return null;
  const { token, sessions } = data as { token?: unknown; sessions?: unknown };
  if (!isValidToken(token)) return null;
  const list = Array.isArray(sessions) ? sessions.filter((s): s is string => typeof s === 'string' && s.length > 0) : [];
  if (list.length === 0) return null;
  return { token, sessions: [...new Set(list)] };
}

function sessionStore(): TokenStorage | null {
  try {
    return typeof sessionStorage === 'undefined' ? null : sessionStorage;
  } catch {
    return null; // Storage disabled: the token lives in memory for this page load.
  }
}

export class ControlTokens {
  private held: HeldControl | null;
  private readonly listeners = new Set<() => void>();

  constructor(private readonly storage: TokenStorage | null = sessionStore()) {
    let text: string | null = null;
    try {
      text = storage?.getItem(CONTROL_KEY) ?? null;
    } catch {
      text = null;
    }
    this.held = parseHeld(text);
  }

  /** The token to send, or null when this tab holds no control. */
  token(): string | null {
    return this.held?.token ?? null;
  }

  sessions(): readonly string[] {
    return this.held?.sessions ?? [];
  }

  holds(sid: string): boolean {
    return this.held?.sessions.includes(sid) ?? false;
  }

  /** What this tab holds now (a copy), or null. */
  snapshot(): HeldControl | null {
    return this.held ? { token: this.held.token, sessions: [...this.held.sessions] } : null;
  }

  /**
   * A take / force take answered `token` for `sid`. A token other than the tab's means the
   * old one held nothing any more (its control lapsed): the sessions listed under it are not
   * held, and the new token starts the list afresh.
   */
  took(sid: string, token: string): void {
    if (!isValidToken(token)) return;
    const prev = this.held;
    const sessions = prev && prev.token === token ? prev.sessions.filter((s) => s !== sid) : [];
    this.save({ token, sessions: [...sessions, sid] });
  }

  /** Released, taken over, lapsed or closed: the tab no longer holds `sid`. The last one
   * clears the token. */
  dropped(sid: string): void {
    const prev = this.held;
    if (!prev || !prev.sessions.includes(sid)) return;
    const sessions = prev.sessions.filter((s) => s !== sid);
    this.save(sessions.length ? { token: prev.token, sessions } : null);
  }

  clear(): void {
    if (this.held) this.save(null);
  }

  /** Called after every change; returns the unsubscribe. */
  subscribe(listener: () => void): () => void {
    this.listeners.add(listener);
    return () => this.listeners.delete(listener);
  }

  private save(next: HeldControl | null): void {
    this.held = next;
    try {
      if (next) this.storage?.setItem(CONTROL_KEY, JSON.stringify(next));
      else if (this.storage?.removeItem) this.storage.removeItem(CONTROL_KEY);
      else this.storage?.setItem(CONTROL_KEY, '');
    } catch {
      // Quota or privacy mode: the token still works for this page load.
    }
    for (const l of this.listeners) l();
  }
}

/** This tab's control token: the one instance the API client, the socket and the UI share. */
export const tabControl = new ControlTokens();

/** The header to add to a request: the token when the tab holds control, else nothing. */
export function controlHeaders(tokens: Pick<ControlTokens, 'token'> = tabControl): Record<string, string> {
  const token = tokens.token();
  return token ? { [CONTROL_HEADER]: token } : {};
}
