/**
 * The pure side of the Backup & restore page's diff viewer: the sources one can compare
 * ("live drive", "profile defaults", any backup), the rows of a Comparison grouped as the
 * profile groups its objects, and each side's value as engineering value with unit and as the
 * raw bytes the drive holds (docs/api.md "Backup, compare, restore").
 */
import type { BackupInfo, CompareSource, Comparison, Difference, GroupInfo, ObjectScalar } from '../api/types';
import { formatEngineering, formatRawBytes, toDec } from './format';
import { backupTitle } from './backupHistory';

/** A source as a select value: "drive", "defaults" or "backup:<id>". */
export type SourceKey = string;

export function sourceKey(s: CompareSource): SourceKey {
  switch (s.kind) {
    case 'drive':
      return 'drive';
    case 'defaults':
      return 'defaults';
    case 'backup':
      return `backup:${s.id}`;
  }
}

/** The source a select value names, for this session and profile; null for an unknown value. */
export function sourceFromKey(key: SourceKey, sid: string, profileId: string): CompareSource | null {
  if (key === 'drive') return { kind: 'drive', session: sid };
  if (key === 'defaults') return { kind: 'defaults', profile: profileId };
  if (key.startsWith('backup:') && key.length > 'backup:'.length) return { kind: 'backup', id: key.slice('backup:'.length) };
  return null;
}

/** Words for a source, e.g. "Live drive", "Profile defaults", "Backup “after tuning” (…)". */
export function sourceLabel(key: SourceKey, backups: readonly BackupInfo[]): string {
  if (key === 'drive') return 'Live drive';
  if (key === 'defaults') return 'Profile defaults';
  const id = key.startsWith('backup:') ? key.slice('backup:'.length) : key;
  const b = backups.find((x) => x.id === id);
  return b ? `Backup: ${backupTitle(b)}` : `Backup ${id}`;
}

export const DIFF_KINDS: ReadonlySet<string> = new Set(['changed', 'only_a', 'only_b']);

export function isDifference(d: Pick<Difference, 'kind'>): boolean {
  return DIFF_KINDS.has(d.kind);
}

export function kindLabel(kind: string): string {
  switch (kind) {
    case 'changed':
      return 'changed';
    case 'only_a':
      return 'only in A';
    case 'only_b':
      return 'only in B';
    default:
      return 'equal';
  }
}

export interface DiffGroup {
  /** The profile's group id (or the text the server sent), '' for entries without a group. */
  id: string;
  name: string;
  rows: Difference[];
  /** How many rows are differences (the rest are equal entries, shown with "show all"). */
  differences: number;
}

/** Sort key of an address "0x6081:00" (index, then subindex); unknown forms sort last. */
export function addressOrder(address: string): number {
  const m = /^0x([0-9a-f]{1,4}):([0-9a-f]{1,2})$/i.exec(address.trim());
  if (!m) return Number.MAX_SAFE_INTEGER;
  return Number.parseInt(m[1] ?? '0', 16) * 256 + Number.parseInt(m[2] ?? '0', 16);
}

/**
 * The comparison's rows grouped in the profile's group order (groups the profile does not
 * know follow, then the ungrouped ones), rows by address. `showAll` false keeps differences
 * only; groups left empty are dropped.
 */
export function groupDifferences(c: Pick<Comparison, 'differences'>, groups: readonly GroupInfo[], showAll: boolean): DiffGroup[] {
  const order = new Map<string, number>();
  const names = new Map<string, string>();
  groups.forEach((g, i) => {
    order.set(g.id, i);
    names.set(g.id, g.name);
    // The server may send the group's name instead of its id.
    if (!order.has(g.name)) order.set(g.name, i);
    names.set(g.name, g.name);
  });
  const byGroup = new Map<string, Difference[]>();
  for (const d of c.differences) {
    if (!showAll && !isDifference(d)) continue;
    const id = d.group ?? '';
    const list = byGroup.get(id);
    if (list) list.push(d);
    else byGroup.set(id, [d]);
  }
  const out: DiffGroup[] = [];
  for (const [id, rows] of byGroup) {
    rows.sort((x, y) => addressOrder(x.address) - addressOrder(y.address) || x.address.localeCompare(y.address));
    out.push({ id, name: id === '' ? 'Not in a group' : (names.get(id) ?? id), rows, differences: rows.filter(isDifference).length });
  }
  const rank = (g: DiffGroup) => (g.id === '' ? Number.MAX_SAFE_INTEGER : (order.get(g.id) ?? groups.length));
  out.sort((x, y) => rank(x) - rank(y) || x.name.localeCompare(y.name));
  return out;
}

export interface DiffCounts {
  changed: number;
  onlyA: number;
  onlyB: number;
  same: number;
}

export function diffCounts(c: Pick<Comparison, 'differences' | 'same'>): DiffCounts {
  let changed = 0;
  let onlyA = 0;
  let onlyB = 0;
  for (const d of c.differences) {
    if (d.kind === 'changed') changed++;
    else if (d.kind === 'only_a') onlyA++;
    else if (d.kind === 'only_b') onlyB++;
  }
  return { changed, onlyA, onlyB, same: c.same };
}

/** "No differences" holds when the server says equal or nothing differs. */
export function isEqual(c: Pick<Comparison, 'equal' | 'differences'>): boolean {
  return c.equal || !c.differences.some(isDifference);
}

function scalarText(v: ObjectScalar | null | undefined): string | null {
  if (v === null || v === undefined) return null;
  if (typeof v === 'number') return toDec(v);
  if (typeof v === 'boolean') return v ? '1' : '0';
  return v;
}

export interface SideCell {
  /** The value in engineering units with its unit, or the plain value with its raw unit. */
  value: string;
  /** The raw bytes as the drive holds them (bus order, hex pairs), '—' when absent. */
  raw: string;
  /** The side has no such entry. */
  absent: boolean;
}

/** One side (A or B) of a row as the viewer shows it. */
export function sideCell(d: Difference, side: 'a' | 'b'): SideCell {
  const eng = side === 'a' ? d.a_engineering : d.b_engineering;
  const value = side === 'a' ? d.a_value : d.b_value;
  const raw = side === 'a' ? d.a_raw_hex : d.b_raw_hex;
  const absent = side === 'a' ? d.kind === 'only_b' : d.kind === 'only_a';
  if (absent && raw == null && value == null) return { value: '—', raw: '—', absent: true };
  let text: string;
  if (eng !== null && eng !== undefined && d.unit) text = formatEngineering(eng, d.unit);
  else {
    const s = scalarText(value);
    text = s === null ? '—' : d.raw_unit && typeof value === 'number' ? `${s} ${d.raw_unit}` : s;
  }
  return { value: text, raw: formatRawBytes(raw), absent };
}
