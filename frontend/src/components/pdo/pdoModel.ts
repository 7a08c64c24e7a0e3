/**
 * The PDO editor's pure model (docs/pdo.md): the draft the page edits, the layout it sends to
 * validate / plan / apply, byte and bit offsets of the entries for display, the bit budget per
 * PDO and per direction, the drag-and-drop moves, the CiA 301 transmission types, the problems
 * grouped by where they are shown, and the live values as "raw · engineering" text.
 *
 * Nothing here talks to the server or React: the page keeps a draft and redraws from it.
 */
import type {
  MappableObject,
  PdoAssignment,
  PdoDirection,
  PdoKind,
  PdoLayout,
  PdoLayoutPdo,
  PdoLiveValue,
  PdoOut,
  PdoProblem,
  PdoView,
} from '../../api/types';
import { formatAddress } from '../../lib/address';
import { formatEngineering, toDec } from '../../lib/format';

/** One mapping entry (CiA 301 §7.5.2.36: index, subindex, length in bits). */
export interface DraftEntry {
  index: number;
  subindex: number;
  bits: number;
}

/** Communication parameters (CiA 301 §7.5.2.35 RPDO, §7.5.2.37 TPDO). */
export interface DraftComm {
  /** 11-bit CAN identifier (COB-ID bits 10..0). */
  cob_id: number;
  /** COB-ID bit 31 clear. */
  enabled: boolean;
  /** TPDO COB-ID bit 30 clear. */
  rtr_allowed: boolean;
  transmission_type: number;
  /** 100 µs units. */
  inhibit_time: number;
  /** ms. */
  event_timer: number;
  sync_start: number;
}

export interface DraftPdo {
  direction: PdoDirection;
  number: number;
  name: string;
  mapping_index: number;
  comm_index: number | null;
  /** Null when the family has no communication parameters (ethercat, fixed, telegram). */
  comm: DraftComm | null;
  entries: DraftEntry[];
}

export interface Draft {
  pdos: DraftPdo[];
  assignment: PdoAssignment | null;
  telegram: number | null;
}

export const DIRECTIONS: readonly PdoDirection[] = ['rx', 'tx'];

export function pdoKey(p: { direction: PdoDirection; number: number }): string {
  return `${p.direction}${p.number}`;
}

export function hex(n: number, digits = 4): string {
  return `${n.toString(16).toUpperCase().padStart(digits, '0')}h`;
}

/** Padding: LECSN Reserved (index 0, 004 §20.1.2) or a CiA 301 dummy entry (0002h..0007h). */
export function isPadding(e: { index: number }): boolean {
  return e.index === 0 || (e.index >= 0x0002 && e.index <= 0x0007);
}

export function entryAddress(e: DraftEntry): string | null {
  return isPadding(e) ? null : formatAddress({ index: e.index, subindex: e.subindex });
}

/** The mapping entry's raw value, e.g. 60640020h (index << 16 | subindex << 8 | bits). */
export function entryRawHex(e: DraftEntry): string {
  const raw = ((e.index & 0xffff) * 0x10000 + ((e.subindex & 0xff) << 8) + (e.bits & 0xff)) >>> 0;
  return `0x${raw.toString(16).toUpperCase().padStart(8, '0')}`;
}

function commOf(p: PdoOut): DraftComm | null {
  if (p.comm_index === null || p.comm_index === undefined) return null;
  return {
    cob_id: (p.cob_id ?? 0) & 0x7ff,
    enabled: p.enabled ?? false,
    rtr_allowed: p.rtr_allowed ?? true,
    transmission_type: p.transmission_type ?? 255,
    inhibit_time: p.inhibit_time ?? 0,
    event_timer: p.event_timer ?? 0,
    sync_start: p.sync_start ?? 0,
  };
}

/** The draft of a view (as read from the drive, or a template's result). */
export function draftFromView(view: PdoView): Draft {
  const pdos = view.pdos.map<DraftPdo>((p) => ({
    direction: p.direction,
    number: p.number,
    name: p.name,
    mapping_index: p.mapping_index,
    comm_index: p.comm_index,
    comm: commOf(p),
    entries: p.entries.map((e) => ({ index: e.index, subindex: e.subindex, bits: e.bits })),
  }));
  // RX first, then TX, each by number (docs/pdo.md: PdoConfig.pdos is RX first).
  pdos.sort((a, b) => (a.direction === b.direction ? a.number - b.number : a.direction === 'rx' ? -1 : 1));
  return {
    pdos,
    assignment: view.assignment ? { rx: [...view.assignment.rx], tx: [...view.assignment.tx] } : null,
    telegram: view.telegram,
  };
}

/** The body of validate / plan / apply: every PDO of the draft, in full. */
export function layoutFromDraft(draft: Draft): PdoLayout {
  const pdos = draft.pdos.map<PdoLayoutPdo>((p) => {
    const out: PdoLayoutPdo = {
      direction: p.direction,
      number: p.number,
      entries: p.entries.map((e) => ({ index: e.index, subindex: e.subindex, bits: e.bits })),
    };
    if (p.comm) {
      out.cob_id = p.comm.cob_id;
      out.enabled = p.comm.enabled;
      if (p.direction === 'tx') out.rtr_allowed = p.comm.rtr_allowed;
      out.transmission_type = p.comm.transmission_type;
      out.inhibit_time = p.comm.inhibit_time;
      out.event_timer = p.comm.event_timer;
      out.sync_start = p.comm.sync_start;
    }
    return out;
  });
  const layout: PdoLayout = { pdos };
  if (draft.assignment) layout.assignment = { rx: [...draft.assignment.rx], tx: [...draft.assignment.tx] };
  if (draft.telegram !== null) layout.telegram = draft.telegram;
  return layout;
}

function sameEntries(a: readonly DraftEntry[], b: readonly DraftEntry[]): boolean {
  return a.length === b.length && a.every((e, i) => e.index === b[i]?.index && e.subindex === b[i]?.subindex && e.bits === b[i]?.bits);
}

function sameComm(a: DraftComm | null, b: DraftComm | null): boolean {
  if (!a || !b) return a === b;
  return (
    a.cob_id === b.cob_id &&
    a.enabled === b.enabled &&
    a.rtr_allowed === b.rtr_allowed &&
    a.transmission_type === b.transmission_type &&
    a.inhibit_time === b.inhibit_time &&
    a.event_timer === b.event_timer &&
    a.sync_start === b.sync_start
  );
}

/** Names of the PDOs whose entries or communication parameters differ from `base`. */
export function changedPdos(draft: Draft, base: Draft | null): Set<string> {
  const out = new Set<string>();
  for (const p of draft.pdos) {
    const b = base?.pdos.find((x) => x.direction === p.direction && x.number === p.number);
    if (!b || !sameEntries(p.entries, b.entries) || !sameComm(p.comm, b.comm)) out.add(p.name);
  }
  return out;
}

function sameList(a: readonly number[] | undefined, b: readonly number[] | undefined): boolean {
  return (a ?? []).length === (b ?? []).length && (a ?? []).every((x, i) => x === (b ?? [])[i]);
}

/** The draft differs from `base` anywhere (PDOs, sync manager assignment, telegram). */
export function draftChanged(draft: Draft, base: Draft | null): boolean {
  if (!base) return true;
  if (changedPdos(draft, base).size) return true;
  if (draft.telegram !== base.telegram) return true;
  return !sameList(draft.assignment?.rx, base.assignment?.rx) || !sameList(draft.assignment?.tx, base.assignment?.tx);
}

// ---------------------------------------------------------------------------------------------
// Offsets and budgets
// ---------------------------------------------------------------------------------------------

export interface EntryOffset {
  /** Bits from the start of the frame. */
  offset_bits: number;
  /** The byte the entry starts in. */
  byte: number;
  /** The bit within that byte (0 unless a previous entry was not a whole number of bytes). */
  bit: number;
}

/** Where each entry sits in the frame: entries follow each other without gaps (CiA 301 §7.5.2.36). */
export function entryOffsets(entries: readonly { bits: number }[]): EntryOffset[] {
  let at = 0;
  return entries.map((e) => {
    const o = { offset_bits: at, byte: Math.floor(at / 8), bit: at % 8 };
    at += e.bits;
    return o;
  });
}

export function totalBits(entries: readonly { bits: number }[]): number {
  return entries.reduce((s, e) => s + e.bits, 0);
}

/** CAN FD data lengths (ISO 11898-1: 0-8, 12, 16, 20, 24, 32, 48, 64 bytes). */
export const CAN_FD_LENGTHS: readonly number[] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/**
 * Bytes on the bus: a classic CAN PDO carries exactly its bytes (at most 8); the families that
 * stand in for EtherCAT / PROFINET on the twin's CAN FD bus pad to the next CAN FD length
 * (docs/pdo.md "Families"). Null when the data does not fit one frame.
 */
export function frameLength(bytes: number, kind: PdoKind): number | null {
  if (kind === 'canopen') return bytes <= 8 ? bytes : null;
  return CAN_FD_LENGTHS.find((n) => n >= bytes) ?? null;
}

export interface BitBudget {
  bits: number;
  maxBits: number;
  bytes: number;
  entries: number;
  maxEntries: number;
  /** Used / max, 0..1 (can exceed 1 when over). */
  fraction: number;
  over: boolean;
  tooManyEntries: boolean;
}

export function bitBudget(entries: readonly { bits: number }[], maxBits: number, maxEntries: number): BitBudget {
  const bits = totalBits(entries);
  return {
    bits,
    maxBits,
    bytes: Math.ceil(bits / 8),
    entries: entries.length,
    maxEntries,
    fraction: maxBits > 0 ? bits / maxBits : 0,
    over: bits > maxBits,
    tooManyEntries: entries.length > maxEntries,
  };
}

/** A PDO goes on the bus: enabled (canopen), assigned to its sync manager (ethercat), always (fixed, telegram). */
export function isActive(p: DraftPdo, draft: Draft, kind: PdoKind): boolean {
  if (kind === 'ethercat') return (draft.assignment?.[p.direction] ?? []).includes(p.mapping_index);
  if (kind === 'canopen') return p.comm ? p.comm.enabled : p.entries.length > 0;
  return true;
}

export interface DirectionBudget {
  direction: PdoDirection;
  bytes: number;
  maxBytes: number | null;
  over: boolean;
  /** Names of the PDOs counted. */
  pdos: string[];
}

/** Bytes of the active PDOs of one direction against the family's limit (HIWIN 000 §2.2: 40 bytes). */
export function directionBudget(draft: Draft, direction: PdoDirection, kind: PdoKind, maxBytes: number | null): DirectionBudget {
  const active = draft.pdos.filter((p) => p.direction === direction && isActive(p, draft, kind));
  const bytes = active.reduce((s, p) => s + Math.ceil(totalBits(p.entries) / 8), 0);
  return { direction, bytes, maxBytes, over: maxBytes !== null && bytes > maxBytes, pdos: active.map((p) => p.name) };
}

export interface TelegramBudget {
  telegram: number;
  /** The telegram's size in bytes: the mapping must fill it exactly (004 §20.1.2). */
  size: number;
  bytes: number;
  /** Bytes still to fill with Reserved entries (negative: too long). */
  missing: number;
}

export function telegramBudget(telegram: number, sizeBits: number, entries: readonly { bits: number }[]): TelegramBudget {
  const size = Math.floor(sizeBits / 8);
  const bytes = Math.ceil(totalBits(entries) / 8);
  return { telegram, size, bytes, missing: size - bytes };
}

// ---------------------------------------------------------------------------------------------
// Editing: drag and drop, keyboard add, remove
// ---------------------------------------------------------------------------------------------

/**
 * Move item `from` so it lands before the item that is at `to` now (`to` = length: the end).
 * This is what a drop on a row means: "put it here, before this one".
 */
export function moveItem<T>(list: readonly T[], from: number, to: number): T[] {
  if (from < 0 || from >= list.length) return list.slice();
  const target = Math.max(0, Math.min(list.length, to));
  if (target === from || target === from + 1) return list.slice();
  const out = list.slice();
  const [item] = out.splice(from, 1);
  out.splice(target > from ? target - 1 : target, 0, item as T);
  return out;
}

export function insertItem<T>(list: readonly T[], item: T, at: number): T[] {
  const out = list.slice();
  out.splice(Math.max(0, Math.min(list.length, at)), 0, item);
  return out;
}

/** What is being dragged: an object from the palette, or an entry of a PDO. */
export type DragItem =
  | { kind: 'object'; direction: PdoDirection | 'both'; entry: DraftEntry }
  | { kind: 'entry'; pdo: string; from: number };

/** Where it is dropped: before entry `at` of PDO `pdo` (`at` = entry count: the end). */
export interface DropTarget {
  pdo: string;
  at: number;
}

/** Entry payloads on the drag's DataTransfer (so another tab or a test can read the drag). */
export const DRAG_MIME = 'application/x-servodesk-pdo';

export function encodeDrag(item: DragItem): string {
  return JSON.stringify(item);
}

export function decodeDrag(text: string): DragItem | null {
  try {
    const d = JSON.parse(text) as Partial<DragItem> & Record<string, unknown>;
    if (d.kind === 'entry' && typeof d.pdo === 'string' && typeof d.from === 'number') return { kind: 'entry', pdo: d.pdo, from: d.from };
    if (d.kind === 'object' && d.entry && typeof d.entry === 'object') {
      const e = d.entry as Partial<DraftEntry>;
      const direction = d.direction === 'rx' || d.direction === 'tx' ? d.direction : 'both';
      if (typeof e.index === 'number' && typeof e.subindex === 'number' && typeof e.bits === 'number') {
        return { kind: 'object', direction, entry: { index: e.index, subindex: e.subindex, bits: e.bits } };
      }
    }
  } catch {
    // Not ours.
  }
  return null;
}

export function entryOfObject(o: Pick<MappableObject, 'index' | 'subindex' | 'bits'>): DraftEntry {
  return { index: o.index, subindex: o.subindex, bits: o.bits };
}

/** Whether `item` may be dropped into PDO `p` (an object of the other direction may not). */
export function canDrop(draft: Draft, item: DragItem, p: DraftPdo): boolean {
  if (item.kind === 'object') return item.direction === 'both' || item.direction === p.direction;
  const src = draft.pdos.find((x) => pdoKey(x) === item.pdo);
  return !!src && src.direction === p.direction;
}

function withEntries(draft: Draft, key: string, fn: (entries: DraftEntry[]) => DraftEntry[]): Draft {
  return { ...draft, pdos: draft.pdos.map((p) => (pdoKey(p) === key ? { ...p, entries: fn(p.entries) } : p)) };
}

/**
 * The draft after a drop: a palette object is inserted; an entry is moved within its PDO or
 * to another PDO of the same direction. A drop that is not allowed leaves the draft as it is.
 */
export function applyDrop(draft: Draft, item: DragItem, target: DropTarget): Draft {
  const dest = draft.pdos.find((p) => pdoKey(p) === target.pdo);
  if (!dest || !canDrop(draft, item, dest)) return draft;
  if (item.kind === 'object') return withEntries(draft, target.pdo, (es) => insertItem(es, item.entry, target.at));
  if (item.pdo === target.pdo) return withEntries(draft, target.pdo, (es) => moveItem(es, item.from, target.at));
  const src = draft.pdos.find((p) => pdoKey(p) === item.pdo);
  const moved = src?.entries[item.from];
  if (!moved) return draft;
  const removed = withEntries(draft, item.pdo, (es) => es.filter((_, i) => i !== item.from));
  return withEntries(removed, target.pdo, (es) => insertItem(es, moved, target.at));
}

export function addEntry(draft: Draft, key: string, entry: DraftEntry): Draft {
  return withEntries(draft, key, (es) => [...es, entry]);
}

export function removeEntry(draft: Draft, key: string, at: number): Draft {
  return withEntries(draft, key, (es) => es.filter((_, i) => i !== at));
}

export function setComm(draft: Draft, key: string, patch: Partial<DraftComm>): Draft {
  return { ...draft, pdos: draft.pdos.map((p) => (pdoKey(p) === key && p.comm ? { ...p, comm: { ...p.comm, ...patch } } : p)) };
}

// ---------------------------------------------------------------------------------------------
// CiA 301 communication parameters
// ---------------------------------------------------------------------------------------------

/** Transmission type choices of the select; "n" is 1-240 with the number beside it. */
export type TransmissionChoice = '0' | 'n' | '252' | '253' | '254' | '255' | 'reserved';

/**
 * CiA 301 §7.5.2.35 (RPDO) / §7.5.2.37 (TPDO), table 71: 0 synchronous acyclic, 1-240
 * synchronous every n-th SYNC, 241-251 reserved, 252/253 RTR-only (TPDO only), 254/255
 * event-driven (manufacturer-specific / device profile).
 */
export function transmissionChoice(tt: number): TransmissionChoice {
  if (tt === 0) return '0';
  if (tt >= 1 && tt <= 240) return 'n';
  if (tt === 252 || tt === 253 || tt === 254 || tt === 255) return String(tt) as TransmissionChoice;
  return 'reserved';
}

export function transmissionOptions(direction: PdoDirection): Array<{ value: TransmissionChoice; label: string }> {
  const all: Array<{ value: TransmissionChoice; label: string; tx?: boolean }> = [
    { value: '0', label: '0 · synchronous, acyclic' },
    { value: 'n', label: '1-240 · synchronous, every n-th SYNC' },
    { value: '252', label: '252 · RTR only, synchronous', tx: true },
    { value: '253', label: '253 · RTR only, event-driven', tx: true },
    { value: '254', label: '254 · event-driven (manufacturer-specific)' },
    { value: '255', label: '255 · event-driven (device profile)' },
  ];
  return all.filter((o) => direction === 'tx' || !o.tx).map(({ value, label }) => ({ value, label }));
}

/** The transmission type a choice stands for (`n` keeps the current 1-240, else 1). */
export function transmissionFromChoice(choice: TransmissionChoice, current: number): number {
  if (choice === 'n') return current >= 1 && current <= 240 ? current : 1;
  if (choice === 'reserved') return current;
  return Number(choice);
}

export function transmissionText(tt: number): string {
  if (tt === 0) return 'synchronous, acyclic';
  if (tt >= 1 && tt <= 240) return tt === 1 ? 'synchronous, every SYNC' : `synchronous, every ${tt}th SYNC`;
  if (tt === 252) return 'RTR only, synchronous';
  if (tt === 253) return 'RTR only, event-driven';
  if (tt === 254) return 'event-driven (manufacturer-specific)';
  if (tt === 255) return 'event-driven (device profile)';
  return `reserved (${tt})`;
}

/** Inhibit time in ms from the raw value (100 µs units, CiA 301 §7.5.2.37 sub 3). */
export function inhibitMs(raw: number): number {
  return Math.round(raw) / 10;
}

export function inhibitRaw(ms: number): number {
  return Math.round(ms * 10);
}

/** An 11-bit COB-ID as typed: "281", "0x281", "281h". Null when it is not one. */
export function parseCobId(text: string): number | null {
  const m = /^\s*(?:0x)?([0-9a-f]{1,3})h?\s*$/i.exec(text);
  if (!m) return null;
  const v = Number.parseInt(m[1] ?? '', 16);
  return v >= 1 && v <= 0x7ff ? v : null;
}

export function cobIdText(v: number): string {
  return `0x${v.toString(16).toUpperCase().padStart(3, '0')}`;
}

// ---------------------------------------------------------------------------------------------
// Problems in place
// ---------------------------------------------------------------------------------------------

export interface PdoProblems {
  /** About the PDO as a whole (no entry, no field other than "entries"). */
  pdo: PdoProblem[];
  /** By 0-based entry position. */
  entries: Map<number, PdoProblem[]>;
  /** By field ("cob_id", "transmission_type", ...). */
  fields: Map<string, PdoProblem[]>;
}

export interface GroupedProblems {
  /** Not about one PDO (assignment, telegram, the direction's byte budget, ...). */
  general: PdoProblem[];
  byPdo: Map<string, PdoProblems>;
  count: number;
}

function push<K, V>(m: Map<K, V[]>, k: K, v: V): void {
  const list = m.get(k);
  if (list) list.push(v);
  else m.set(k, [v]);
}

/** Where each problem is shown: next to its entry, its field, its PDO, or above the tables. */
export function groupProblems(problems: readonly PdoProblem[], pdoNames: ReadonlySet<string>): GroupedProblems {
  const byPdo = new Map<string, PdoProblems>();
  const general: PdoProblem[] = [];
  for (const p of problems) {
    if (!p.pdo || !pdoNames.has(p.pdo)) {
      general.push(p);
      continue;
    }
    let g = byPdo.get(p.pdo);
    if (!g) {
      g = { pdo: [], entries: new Map(), fields: new Map() };
      byPdo.set(p.pdo, g);
    }
    if (p.entry !== null && p.entry !== undefined) push(g.entries, p.entry, p);
    else if (p.field && p.field !== 'entries') push(g.fields, p.field, p);
    else g.pdo.push(p);
  }
  return { general, byPdo, count: problems.length };
}

// ---------------------------------------------------------------------------------------------
// Names and live values
// ---------------------------------------------------------------------------------------------

/** CiA 301 §7.4.7.1 table 44 data type numbers (as EDS files write them, CiA 306). */
const DATA_TYPE_NAMES: Record<number, string> = {
  0x01: 'BOOLEAN',
  0x02: 'INTEGER8',
  0x03: 'INTEGER16',
  0x04: 'INTEGER32',
  0x05: 'UNSIGNED8',
  0x06: 'UNSIGNED16',
  0x07: 'UNSIGNED32',
  0x08: 'REAL32',
  0x09: 'VISIBLE_STRING',
  0x0a: 'OCTET_STRING',
  0x0b: 'UNICODE_STRING',
  0x0f: 'DOMAIN',
  0x10: 'INTEGER24',
  0x11: 'REAL64',
  0x12: 'INTEGER40',
  0x13: 'INTEGER48',
  0x14: 'INTEGER56',
  0x15: 'INTEGER64',
  0x16: 'UNSIGNED24',
  0x18: 'UNSIGNED40',
  0x19: 'UNSIGNED48',
  0x1a: 'UNSIGNED56',
  0x1b: 'UNSIGNED64',
};

/** A data type as a name, whether the server sends the name or the CiA 306 number. */
export function dataTypeName(t: string | number | null | undefined): string | null {
  if (t === null || t === undefined) return null;
  if (typeof t === 'number') return DATA_TYPE_NAMES[t] ?? `type 0x${t.toString(16).toUpperCase().padStart(4, '0')}`;
  return t;
}

// ---------------------------------------------------------------------------------------------
// Live values
// ---------------------------------------------------------------------------------------------

export interface ObjectDescription {
  name: string;
  data_type: string | null;
  unit: string | null;
  raw_unit?: string | null;
}

/** Name, type and unit by address, from the palette and every view seen. */
export function describeFrom(mappable: readonly MappableObject[], views: ReadonlyArray<PdoView | null>): Map<string, ObjectDescription> {
  const m = new Map<string, ObjectDescription>();
  for (const v of views) {
    for (const p of v?.pdos ?? []) {
      for (const e of p.entries) {
        if (e.address && !e.padding) m.set(e.address.toUpperCase(), { name: e.name, data_type: dataTypeName(e.data_type), unit: e.unit });
      }
    }
  }
  for (const o of mappable) m.set(o.address.toUpperCase(), { name: o.name, data_type: dataTypeName(o.data_type), unit: o.unit });
  return m;
}

export function paddingName(e: DraftEntry): string {
  return e.index === 0 ? `Reserved (${e.bits} bits)` : `Dummy ${hex(e.index)} (${e.bits} bits)`;
}

/** Live value text: the raw value with its raw unit, and the engineering value with its unit. */
export function formatLive(v: PdoLiveValue, rawUnit: string | null | undefined): { raw: string; eng: string | null } {
  const r = v.value;
  let raw: string;
  if (typeof r === 'number') raw = toDec(r);
  else if (typeof r === 'boolean') raw = r ? '1' : '0';
  else raw = r;
  const eng = v.engineering;
  const knownRaw = v.raw_unit ?? rawUnit ?? null;
  // Scaled (another number or another unit): both. Unscaled: one number with its unit.
  const scaled = typeof eng === 'number' && (eng !== r || (!!v.unit && !!knownRaw && v.unit !== knownRaw));
  const ru = knownRaw ?? (scaled ? null : v.unit);
  // A raw unit that is a step ("0.1 %", "100 µs") reads as a multiple of it.
  if (ru) raw = /^[\d.]/.test(ru) ? `${raw} × ${ru}` : `${raw} ${ru}`;
  const hasEng = scaled;
  return { raw, eng: hasEng ? formatEngineering(eng, v.unit) : null };
}

/** Filter the palette: the direction's objects whose address, name or type contain every word. */
export function filterMappable(list: readonly MappableObject[], query: string): MappableObject[] {
  const words = query.trim().toLowerCase().split(/\s+/).filter(Boolean);
  if (!words.length) return list.slice();
  return list.filter((o) => {
    const hay = `${o.address} ${o.address.replace(/^0x/i, '').replace(':', ' ')} ${hex(o.index)} ${o.name} ${dataTypeName(o.data_type)} ${o.unit ?? ''}`.toLowerCase();
    return words.every((w) => hay.includes(w));
  });
}
