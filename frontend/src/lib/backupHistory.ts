/**
 * The pure side of the backup history: which backups belong to this drive, how a backup is
 * named and dated on screen, and the names of downloaded files (docs/api.md "Backup, compare,
 * restore"; BackupInfo).
 */
import type { BackupFormat, BackupInfo, Identity } from '../api/types';

/**
 * The same physical drive: vendor, product code and serial number agree (CiA 301 1018h). A
 * backup without a serial cannot be told apart from its siblings, so it does not match.
 */
export function sameDrive(a: Partial<Identity> | null | undefined, b: Partial<Identity> | null | undefined): boolean {
  if (!a || !b) return false;
  if (a.serial == null || b.serial == null) return false;
  return a.vendor_id === b.vendor_id && a.product_code === b.product_code && a.serial === b.serial;
}

/**
 * The drive key of the session's drive: the session's own `drive_key` when the server sends
 * it, else the key of a backup taken of the same drive (same identity), else null.
 */
export function driveKeyOf(session: { drive_key?: string | null; identity: Identity } | null, backups: readonly BackupInfo[]): string | null {
  if (!session) return null;
  if (session.drive_key) return session.drive_key;
  return backups.find((b) => sameDrive(b.identity, session.identity))?.drive_key ?? null;
}

/** Seconds since the epoch or ISO text -> Date (null when unreadable). */
export function toDate(t: string | number | null | undefined): Date | null {
  if (t === null || t === undefined || t === '') return null;
  const d = typeof t === 'number' ? new Date(t < 1e11 ? t * 1000 : t) : new Date(t);
  return Number.isNaN(d.getTime()) ? null : d;
}

function pad(n: number): string {
  return n.toString().padStart(2, '0');
}

/** "2025-11-21 15:04:09" in local time: sortable, unambiguous, as engineers write logs. */
export function formatTime(t: string | number | null | undefined): string {
  const d = toDate(t);
  if (!d) return t === null || t === undefined ? '—' : String(t);
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())} ${pad(d.getHours())}:${pad(d.getMinutes())}:${pad(d.getSeconds())}`;
}

/** How a backup is named in lists: its label, else its time. */
export function backupTitle(b: Pick<BackupInfo, 'label' | 'time'>): string {
  const label = b.label.trim();
  return label ? `“${label}” · ${formatTime(b.time)}` : formatTime(b.time);
}

/** A safe file name for a download the server did not name. */
export function downloadName(b: Pick<BackupInfo, 'id' | 'label' | 'profile_id'>, format: BackupFormat): string {
  const base = `${b.profile_id}-${b.label.trim() || b.id}`
    .toLowerCase()
    .replace(/[^a-z0-9._-]+/g, '-')
    .replace(/-+/g, '-')
    .replace(/^-|-$/g, '');
  return `${base || 'backup'}.${format}`;
}

/** Files the upload takes: a JSON backup or a DCF (docs/api.md POST /backups/upload). */
export function uploadProblem(filename: string, size: number): string | null {
  if (!/\.(json|dcf)$/i.test(filename)) return `${filename} is neither a JSON backup nor a DCF file`;
  if (size === 0) return `${filename} is empty`;
  if (size > 16 * 1024 * 1024) return `${filename} is larger than 16 MiB`;
  return null;
}

/** Serial number as the drive's nameplate shows it. */
export function serialText(identity: Partial<Identity> | null | undefined): string {
  const s = identity?.serial;
  return s === null || s === undefined ? '—' : String(s);
}
