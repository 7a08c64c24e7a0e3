/**
 * The pure side of the restore wizard (docs/api.md "Backup, compare, restore"): when Restore
 * may run, what a report's statuses mean in words, and what the report says as a whole.
 * DESIGN.md "Rules that hold everywhere": a restore reports every item and stores to
 * non-volatile memory only after it verified.
 */
import type { Preflight, RestoreItem, RestoreItemStatus, RestoreReport } from '../api/types';

export interface RestoreOptions {
  dryRun: boolean;
  store: boolean;
  force: boolean;
}

export const DEFAULT_OPTIONS: RestoreOptions = { dryRun: false, store: true, force: false };

/**
 * Why Restore cannot run now, or null when it can. A failed preflight blocks it. A backup of
 * another family (`otherFamily`: its profile is not the drive's) needs the opt-in to map
 * entries by name; the server sends the mapping only once asked (map_by_name: true).
 */
export function restoreBlocker(preflight: Preflight | null, mapByName: boolean, otherFamily = false): string | null {
  if (!preflight) return 'run the preflight check first';
  if (otherFamily && !mapByName) return 'the backup is of another drive family: opt in to map entries by name';
  if (!preflight.ok) {
    const n = preflight.problems.length;
    return n === 1 ? 'the preflight found a problem; fix it and check again' : `the preflight found ${n} problems; fix them and check again`;
  }
  if (preflight.mapping && !mapByName) return 'the backup is of another drive family: opt in to map entries by name';
  return null;
}

/** Why a (real, not dry) restore would do nothing: every entry already holds the backup's value. */
export function nothingToWrite(preflight: Preflight | null, dryRun: boolean): string | null {
  if (!preflight || dryRun || preflight.to_write > 0) return null;
  return 'nothing to write: the drive already holds every value of the backup';
}

/** How many entries of a name mapping found a target on this drive. */
export function mappedCount(mapping: Preflight['mapping']): { mapped: number; unmapped: number } {
  if (!mapping) return { mapped: 0, unmapped: 0 };
  const mapped = mapping.filter((m) => m.target !== null).length;
  return { mapped, unmapped: mapping.length - mapped };
}

export function statusLabel(s: RestoreItemStatus | string): string {
  switch (s) {
    case 'written':
      return 'written';
    case 'unchanged':
      return 'unchanged';
    case 'skipped_read_only':
      return 'skipped (read-only)';
    case 'failed':
      return 'failed';
    case 'pending':
      return 'not yet written';
    case 'would_write':
      return 'would write';
    default:
      return s;
  }
}

/** CSS class of a status: good, neutral, warning, bad. */
export function statusClass(s: RestoreItemStatus | string): string {
  switch (s) {
    case 'written':
      return 'st-written';
    case 'would_write':
      return 'st-would';
    case 'failed':
      return 'st-failed';
    case 'pending':
      return 'st-pending';
    default:
      return 'st-neutral';
  }
}

/** Failures first, then not-yet-written, then writes, then the quiet rest, each by address. */
export function sortItems(items: readonly RestoreItem[]): RestoreItem[] {
  const rank: Record<string, number> = { failed: 0, pending: 1, would_write: 2, written: 3, unchanged: 4, skipped_read_only: 5 };
  return items.slice().sort((a, b) => (rank[a.status] ?? 9) - (rank[b.status] ?? 9) || a.address.localeCompare(b.address));
}

/** The report's verdict in one line, and how it went. */
export function reportVerdict(r: RestoreReport): { kind: 'ok' | 'warn' | 'bad'; text: string } {
  const c = r.counts;
  if (r.interrupted || (!r.finished && c.pending > 0)) {
    return { kind: 'bad', text: `Interrupted: ${c.pending} entr${c.pending === 1 ? 'y' : 'ies'} not yet written. Resume continues with them.` };
  }
  if (c.failed > 0) {
    const stored = r.stored ? 'the rest was stored to non-volatile memory' : 'nothing was stored to non-volatile memory';
    return { kind: 'bad', text: `${c.failed} entr${c.failed === 1 ? 'y' : 'ies'} failed (see the abort codes below); ${stored}.` };
  }
  if (r.dry_run) {
    const would = r.items.filter((i) => i.status === 'would_write').length;
    return { kind: 'ok', text: `Dry run: ${would} entr${would === 1 ? 'y' : 'ies'} would be written; nothing was written.` };
  }
  const stored = r.stored ? ' and stored to non-volatile memory' : ' (not stored to non-volatile memory)';
  return { kind: r.stored ? 'ok' : 'warn', text: `Restored: ${c.written} written, ${c.unchanged} unchanged, all verified${stored}.` };
}

/** An interrupted restore can be resumed (entries not yet verified remain). */
export function canResume(r: RestoreReport | null): boolean {
  return !!r && !r.dry_run && (r.interrupted || (!r.finished && r.counts.pending > 0));
}
