/**
 * Object dictionary helpers for the Parameters and Object dictionary pages: which objects are
 * configuration parameters, group order, access and PDO tests, "differs from default", and a
 * precomputed lowercase search index that accepts the ways manuals write an address (6040,
 * 0x6040, 6040h, 6040h.1, and the PROFIdrive parameter number P24640, LECSN manual §20.1.5.1:
 * PNU in decimal = the CoE index).
 *
 * The search index is built once per profile so a keystroke only runs `includes` over ~3000
 * short strings (lecsn-t has 2912 objects) instead of rebuilding text per row.
 */
import type { GroupInfo, ObjectInfo, ObjectScalar, ProfileDetail } from '../api/types';

export function isReadable(o: Pick<ObjectInfo, 'access'>): boolean {
  return o.access !== 'wo';
}

export function isWritable(o: Pick<ObjectInfo, 'access'>): boolean {
  return /w/i.test(o.access);
}

export function isPdoMappable(o: Pick<ObjectInfo, 'pdo_mapping'>): boolean {
  return !!o.pdo_mapping && o.pdo_mapping !== 'none' && o.pdo_mapping !== 'no';
}

/** A configuration parameter: set by the user and kept by the drive, not a process value. */
export function isParameter(o: ObjectInfo): boolean {
  return !o.process && isWritable(o);
}

export const OTHER_GROUP: GroupInfo = { id: '', name: 'Other', name_local: null, description: 'Objects without a group' };

export interface GroupOf<T> {
  group: GroupInfo;
  objects: T[];
}

/** Objects grouped by `group`, in the profile's group order; objects without a group last. */
export function groupObjects(profile: Pick<ProfileDetail, 'groups'>, objects: readonly ObjectInfo[]): GroupOf<ObjectInfo>[] {
  const by = new Map<string, ObjectInfo[]>();
  for (const o of objects) {
    const k = o.group ?? '';
    let list = by.get(k);
    if (!list) {
      list = [];
      by.set(k, list);
    }
    list.push(o);
  }
  const out: GroupOf<ObjectInfo>[] = [];
  for (const g of profile.groups) {
    const list = by.get(g.id);
    if (list && list.length) out.push({ group: g, objects: list });
    by.delete(g.id);
  }
  // Groups the objects name but the profile does not list, then the ungrouped ones.
  for (const [k, list] of by) {
    if (k === '') continue;
    out.push({ group: { id: k, name: k, name_local: null, description: null }, objects: list });
  }
  const none = by.get('');
  if (none && none.length) out.push({ group: OTHER_GROUP, objects: none });
  return out;
}

/** Whether a profile's objects carry PROFIdrive numbers / drive symbols (show those columns). */
export function hasPnu(objects: readonly ObjectInfo[]): boolean {
  return objects.some((o) => o.pnu !== null && o.pnu !== undefined);
}

export function hasSymbol(objects: readonly ObjectInfo[]): boolean {
  return objects.some((o) => !!o.symbol);
}

/** Equal as the drive sees it: numbers by value, so 1 equals true and "1.0" equals 1. */
export function sameValue(a: ObjectScalar | null | undefined, b: ObjectScalar | null | undefined): boolean {
  if (a === null || a === undefined || b === null || b === undefined) return a === b;
  if (typeof a === 'string' && typeof b === 'string') return a === b;
  const na = typeof a === 'boolean' ? Number(a) : typeof a === 'number' ? a : Number(a);
  const nb = typeof b === 'boolean' ? Number(b) : typeof b === 'number' ? b : Number(b);
  if (Number.isNaN(na) || Number.isNaN(nb)) return String(a) === String(b);
  return na === nb;
}

/** True / false when the live value is known and the profile has a default; null otherwise. */
export function differsFromDefault(o: ObjectInfo, live: ObjectScalar | null | undefined): boolean | null {
  if (live === undefined || live === null || o.default === null || o.default === undefined) return null;
  return !sameValue(live, o.default);
}

/** One haystack per object, lowercase, fields separated by newlines so words do not join. */
export function searchText(o: ObjectInfo): string {
  const hex = o.index.toString(16).padStart(4, '0');
  const parts = [
    o.address,
    `${hex}h`,
    `p${o.pnu ?? o.index}`,
    o.name,
    o.name_local ?? '',
    o.symbol ?? '',
    o.description ?? '',
  ];
  return parts.join('\n').toLowerCase();
}

export function buildSearchIndex(objects: readonly ObjectInfo[]): string[] {
  return objects.map(searchText);
}

const HEX_ADDR = /^(?:0x)?([0-9a-f]{1,4})(h)?(?:[:.](?:0x)?([0-9a-f]{1,2})h?)?$/;
const PNU_Q = /^p(\d{1,5})(?:[.:[](\d{1,3})\]?)?$/;

/**
 * The alternatives one query word matches: the word itself, and for an address the canonical
 * spelling the haystack holds (6040h -> "0x6040:", 6040h.1 -> "0x6040:01", P24640.1 ->
 * "p24640" plus the CoE address). A word matches an object when any alternative is a substring.
 */
export function wordAlternatives(word: string): string[] {
  const w = word.toLowerCase();
  const alts = [w];
  const m = HEX_ADDR.exec(w);
  if (m && (m[2] || m[3] !== undefined || w.startsWith('0x'))) {
    const idx = (m[1] ?? '').padStart(4, '0');
    if (m[3] !== undefined) alts.push(`0x${idx}:${m[3].padStart(2, '0')}`);
    else alts.push(`0x${idx}:`);
  }
  const p = PNU_Q.exec(w);
  if (p) {
    const n = Number.parseInt(p[1] ?? '', 10);
    if (n <= 0xffff) {
      // "p24640" must not also match "p246400": the haystack has "p<number>\n".
      alts.push(`p${n}\n`);
      const hex = n.toString(16).padStart(4, '0');
      if (p[2] !== undefined) alts.push(`0x${hex}:${Number.parseInt(p[2], 10).toString(16).padStart(2, '0')}`);
      else alts.push(`0x${hex}:`);
    }
  }
  return alts;
}

/** A compiled query: every word must match (AND), each by any of its alternatives. */
export type Query = string[][];

export function compileQuery(text: string): Query {
  return text
    .trim()
    .toLowerCase()
    .split(/\s+/)
    .filter(Boolean)
    .map(wordAlternatives);
}

export function matches(haystack: string, q: Query): boolean {
  for (const alts of q) {
    let hit = false;
    for (const a of alts) {
      if (haystack.includes(a)) {
        hit = true;
        break;
      }
    }
    if (!hit) return false;
  }
  return true;
}

export interface DictionaryFilter {
  query: string;
  /** Group id; '' = all groups. */
  group: string;
  access: 'all' | 'readable' | 'writable';
  pdo: boolean;
  /** Only objects whose live value is known and differs from the default. */
  differs: boolean;
}

export const NO_FILTER: DictionaryFilter = { query: '', group: '', access: 'all', pdo: false, differs: false };

/** Indexes (into `objects`) of the objects that pass the filter, in profile order. */
export function filterObjects(
  objects: readonly ObjectInfo[],
  index: readonly string[],
  f: DictionaryFilter,
  live?: (o: ObjectInfo) => ObjectScalar | null | undefined,
): number[] {
  const q = compileQuery(f.query);
  const out: number[] = [];
  for (let i = 0; i < objects.length; i++) {
    const o = objects[i] as ObjectInfo;
    if (f.group && (o.group ?? '') !== f.group) continue;
    if (f.access === 'readable' && !isReadable(o)) continue;
    if (f.access === 'writable' && !isWritable(o)) continue;
    if (f.pdo && !isPdoMappable(o)) continue;
    if (q.length && !matches(index[i] ?? '', q)) continue;
    if (f.differs && differsFromDefault(o, live?.(o)) !== true) continue;
    out.push(i);
  }
  return out;
}

/** Split a list into batches of at most `size` (POST /read takes at most 512 addresses). */
export function batches<T>(items: readonly T[], size: number): T[][] {
  const out: T[][] = [];
  for (let i = 0; i < items.length; i += size) out.push(items.slice(i, i + size));
  return out;
}

/** PROFIdrive parameter number as the LECSN manual writes it: P24640, P10241.3 (§20.1.2). */
export function formatPnu(o: Pick<ObjectInfo, 'pnu' | 'subindex'>): string {
  if (o.pnu === null || o.pnu === undefined) return '';
  return o.subindex ? `P${o.pnu}.${o.subindex}` : `P${o.pnu}`;
}

/** Normalise an address from the API ("0x6081:00", "0x6081") to the profile's spelling. */
export function canonicalAddress(a: string): string {
  const m = /^0x([0-9a-f]{1,4})(?::([0-9a-f]{1,2}))?$/i.exec(a.trim());
  if (!m) return a.trim();
  return `0x${(m[1] ?? '').toUpperCase().padStart(4, '0')}:${(m[2] ?? '0').toUpperCase().padStart(2, '0')}`;
}
