/**
 * Progress of a backup or restore from the WebSocket's `progress` messages (docs/api.md
 * "Backup, compare, restore": operation "backup", and "restore" with one `item` per entry).
 *
 * ws/progress.ts reads only fraction and message; a restore's progress also carries the entry
 * just handled, so this reads the same frames with `item` (and the restore's id, when the
 * server names it, so an interrupted restore can be found again and resumed).
 */
import type { RestoreItem, RestoreItemStatus } from '../api/types';
import { type ProgressWatch, progressSocketUrl, watchMessages } from '../ws/progress';

const STATUSES: ReadonlySet<string> = new Set(['written', 'unchanged', 'skipped_read_only', 'failed', 'pending', 'would_write']);

/** A restore step from a progress message: the address, and what the server adds. */
export type ProgressItem = Partial<RestoreItem> & {
  address: string;
  /** Why this write (e.g. "entry", or a step of a PDO mapping procedure). */
  why?: string;
};

export interface BackupProgress {
  session: string;
  operation: string;
  fraction: number;
  message: string | null;
  /** The entry being written (restore), as far as the message describes it. */
  item: ProgressItem | null;
  /** The restore's id, when the message carries it (`restore`, `rid` or `restore_id`). */
  restoreId: string | null;
}

function str(v: unknown): string | null {
  return typeof v === 'string' && v !== '' ? v : null;
}

function num(v: unknown): number | null {
  return typeof v === 'number' && Number.isFinite(v) ? v : null;
}

/** The `item` of a progress message: an address text or an object like a report item. */
export function parseProgressItem(raw: unknown): BackupProgress['item'] {
  if (typeof raw === 'string') return raw ? { address: raw } : null;
  if (!raw || typeof raw !== 'object') return null;
  const o = raw as Record<string, unknown>;
  const address = str(o.address);
  if (!address) return null;
  const item: ProgressItem = { address };
  const name = str(o.name);
  if (name) item.name = name;
  if (typeof o.status === 'string' && STATUSES.has(o.status)) item.status = o.status as RestoreItemStatus;
  const oldHex = str(o.old_raw_hex);
  if (oldHex) item.old_raw_hex = oldHex;
  const newHex = str(o.new_raw_hex);
  if (newHex) item.new_raw_hex = newHex;
  const code = num(o.code);
  if (code !== null) item.code = code;
  const codeHex = str(o.code_hex);
  if (codeHex) item.code_hex = codeHex;
  const meaning = str(o.meaning);
  if (meaning) item.meaning = meaning;
  const message = str(o.message);
  if (message) item.message = message;
  const why = str(o.why);
  if (why) item.why = why;
  return item;
}

/** One text frame as backup/restore progress, or null when it is anything else. */
export function parseBackupProgress(text: string): BackupProgress | null {
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch {
    return null;
  }
  if (!data || typeof data !== 'object') return null;
  const m = data as Record<string, unknown>;
  if (m.type !== 'progress' || typeof m.session !== 'string') return null;
  const fraction = num(m.fraction);
  if (fraction === null) return null;
  return {
    session: m.session,
    operation: typeof m.operation === 'string' ? m.operation : '',
    fraction: Math.max(0, Math.min(1, fraction)),
    message: str(m.message),
    item: parseProgressItem(m.item),
    restoreId: str(m.restore) ?? str(m.rid) ?? str(m.restore_id),
  };
}

/**
 * Merge a progressed item into the live list: an address seen again is updated in place (what
 * it says later wins), a new one is appended, so the list reads in the order of the restore.
 */
export function mergeProgressItem(items: readonly ProgressItem[], item: ProgressItem): ProgressItem[] {
  const i = items.findIndex((x) => x.address === item.address);
  const merged: ProgressItem = i >= 0 ? { ...(items[i] as ProgressItem), ...item } : item;
  if (i < 0) return [...items, merged];
  const next = items.slice();
  next[i] = merged;
  return next;
}

/**
 * Watch `operation` progress of session `sid` (with the restore's per-item detail) on a
 * short-lived socket of its own; call close() when the operation is over.
 */
export function watchBackupProgress(
  sid: string,
  operation: 'backup' | 'restore',
  onProgress: (m: BackupProgress) => void,
  url: () => string = progressSocketUrl,
): ProgressWatch {
  return watchMessages(sid, operation, parseBackupProgress, onProgress, url);
}
