/**
 * User-facing notices: what failed, why, and what to do. Errors from the API become one
 * notice with the action, the message, the protocol code and its meaning, and the hint —
 * never the JSON body.
 */
import { ApiError } from '../api/client';
import { Observable } from './observable';

export type NoticeKind = 'error' | 'warning' | 'info';

export interface Notice {
  id: number;
  kind: NoticeKind;
  /** What failed or happened, e.g. "Write 0x6041:00 failed". */
  title: string;
  /** Why: the server's message. */
  message: string;
  /** The protocol code and its meaning, e.g. "SDO abort 0x06010002: Attempt to write a read only object". */
  detail: string | null;
  /** What to do. */
  hint: string | null;
  time: number;
}

export const notices = new Observable<Notice[]>([]);
let nextId = 1;
const timers = new Map<number, ReturnType<typeof setTimeout>>();

export function dismiss(id: number): void {
  const t = timers.get(id);
  if (t) clearTimeout(t);
  timers.delete(id);
  notices.update((list) => list.filter((n) => n.id !== id));
}

export function notify(n: Omit<Notice, 'id' | 'time'>, ttlMs?: number): number {
  const id = nextId++;
  // Keep the list short: a person reads the newest, older ones are noise.
  notices.update((list) => [...list.slice(-3), { ...n, id, time: Date.now() }]);
  const ttl = ttlMs ?? (n.kind === 'error' ? 20_000 : n.kind === 'warning' ? 12_000 : 4_000);
  timers.set(
    id,
    setTimeout(() => dismiss(id), ttl),
  );
  return id;
}

/** The protocol code line of an API error, or null when the error has none. */
export function protocolDetail(e: ApiError): string | null {
  const b = e.body;
  if (!b.code_hex && b.code == null && !b.meaning) return null;
  const proto = b.protocol ? `${protocolName(b.protocol)} ` : '';
  const code = b.code_hex ?? (b.code != null ? String(b.code) : '');
  const head = `${proto}${code ? `code ${code}` : ''}`.trim();
  return b.meaning ? (head ? `${head}: ${b.meaning}` : b.meaning) : head;
}

export function protocolName(p: string): string {
  switch (p.toLowerCase()) {
    case 'sdo':
      return 'SDO abort';
    case 'profidrive':
      return 'PROFIdrive error';
    case 'slmp':
      return 'SLMP end code';
    case 'coe':
      return 'CoE abort';
    case 'profile':
      // Refused by the profile check before anything was sent; the code is the one the
      // device would have answered with.
      return 'Profile check';
    default:
      return p;
  }
}

export function describeError(e: unknown): Omit<Notice, 'id' | 'time'> {
  if (e instanceof ApiError) {
    return {
      kind: 'error',
      title: `${e.action} failed`,
      message: e.body.message,
      detail: protocolDetail(e),
      hint: e.body.hint ?? null,
    };
  }
  const message = e instanceof Error ? e.message : String(e);
  return { kind: 'error', title: 'Something failed', message, detail: null, hint: 'reload the page; if it persists, check the server log' };
}

export function notifyError(e: unknown): void {
  notify(describeError(e));
}
