/**
 * The per-tab client id the UI sends as `X-Servodesk-Client` (docs/api.md "Backup, compare,
 * restore"): the server records it in the audit log, so a person can tell which browser tab
 * wrote what. It is made once per tab and kept in sessionStorage, which lives exactly as long
 * as the tab (a reload keeps the id, another tab gets its own).
 */

export const CLIENT_ID_KEY = 'servodesk.client';
export const CLIENT_HEADER = 'X-Servodesk-Client';

/** Storage-like: what the id needs of sessionStorage (a plain object in tests). */
export interface IdStorage {
  getItem(key: string): string | null;
  setItem(key: string, value: string): void;
}

/** A new id, e.g. "ui-3f2a9c1e7b04": "ui-" and 12 hex digits from the random source. */
export function makeClientId(randomBytes: (n: number) => Uint8Array = cryptoBytes): string {
  const bytes = randomBytes(6);
  let hex = '';
  for (const b of bytes) hex += b.toString(16).padStart(2, '0');
  return `ui-${hex}`;
}

function cryptoBytes(n: number): Uint8Array {
  const out = new Uint8Array(n);
  if (typeof crypto !== 'undefined' && typeof crypto.getRandomValues === 'function') {
    crypto.getRandomValues(out);
  } else {
    for (let i = 0; i < n; i++) out[i] = Math.floor(Math.random() * 256);
  }
  return out;
}

/** A header value must be visible ASCII; anything else in storage is replaced. */
export function isValidClientId(id: string | null | undefined): id is string {
  return !!id && /^[\x21-\x7e]{1,100}$/.test(id);
}

function sessionStore(): IdStorage | null {
  try {
    return typeof sessionStorage === 'undefined' ? null : sessionStorage;
  } catch {
    // Storage disabled by privacy settings: the id then lives in memory for this page load.
    return null;
  }
}

let memoryId: string | null = null;

/** This tab's id: from storage, or made now and stored. */
export function tabClientId(storage: IdStorage | null = sessionStore(), make: () => string = makeClientId): string {
  let stored: string | null = null;
  try {
    stored = storage?.getItem(CLIENT_ID_KEY) ?? null;
  } catch {
    stored = null;
  }
  if (isValidClientId(stored)) return stored;
  if (!storage && isValidClientId(memoryId)) return memoryId;
  const id = make();
  memoryId = id;
  try {
    storage?.setItem(CLIENT_ID_KEY, id);
  } catch {
    // Quota or privacy mode: the in-memory id still identifies this page load.
  }
  return id;
}
