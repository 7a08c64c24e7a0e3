/**
 * Entering a value in engineering units (issue 48 "units a person reads"): a person types
 * 3000 rpm, the drive takes 491520 inc/s. The profile gives engineering = raw × scale
 * (backend/servodesk/domain/profile.py ObjectSpec; the session's scale when the drive's
 * encoder differs from the profile's), so raw = engineering / scale, rounded to the nearest
 * whole increment for an integer object (the drive holds no fractions) and checked against
 * the object's raw range before anything is sent. What is sent stays the raw value: the API
 * takes raw values and validates again.
 *
 * Objects with an enumeration (documented values are raw codes), BOOLEAN, strings and byte
 * strings have no engineering entry, nor objects whose unit is the raw one at scale 1.
 */
import type { ObjectInfo } from '../api/types';
import { isIntegerType, isRealType, typeBits } from './format';
import { allowedRange } from './validate';
import { hasEngineering } from './values';

/** How a value is typed: in the engineering unit, or raw (dec or hex). */
export type EntryUnit = 'eng' | 'raw';

/** localStorage key of the browser's choice (like `servodesk.theme`). */
export const ENTRY_UNIT_KEY = 'servodesk.entryUnit';

export type UnitSpec = Pick<ObjectInfo, 'index' | 'name' | 'data_type' | 'access' | 'min' | 'max' | 'unit' | 'scale' | 'raw_unit' | 'values'>;

/** The largest finite REAL32 (IEEE 754 binary32), the bound of a REAL32 object's raw value. */
const REAL32_MAX = 3.4028234663852886e38;

/** Whether an object may be entered in engineering units. */
export function offersEngineeringEntry(spec: UnitSpec): boolean {
  if (!hasEngineering(spec)) return false;
  if (!Number.isFinite(spec.scale) || spec.scale === 0) return false;
  if (spec.values && Object.keys(spec.values).length > 0) return false;
  const dt = spec.data_type;
  return isRealType(dt) || (isIntegerType(dt) && typeBits(dt) !== 1);
}

/** A stored choice: raw only when the person chose raw; engineering by default. */
export function parseEntryUnit(stored: string | null | undefined): EntryUnit {
  return stored === 'raw' ? 'raw' : 'eng';
}

function storage(): Storage | null {
  try {
    return typeof localStorage === 'undefined' ? null : localStorage;
  } catch {
    // Storage can be blocked (privacy settings): the choice then lasts for the page only.
    return null;
  }
}

export function loadEntryUnit(store: Pick<Storage, 'getItem'> | null = storage()): EntryUnit {
  try {
    return parseEntryUnit(store?.getItem(ENTRY_UNIT_KEY));
  } catch {
    return 'eng';
  }
}

export function saveEntryUnit(unit: EntryUnit, store: Pick<Storage, 'setItem'> | null = storage()): void {
  try {
    store?.setItem(ENTRY_UNIT_KEY, unit);
  } catch {
    // Quota or blocked storage: not worth an error, the choice holds for this page.
  }
}

/**
 * An engineering number as text: ten significant digits, no float noise (0.1 × 3 is 0.3),
 * enough that typing it back gives the same raw value.
 */
export function engNumberText(v: number): string {
  if (!Number.isFinite(v)) return String(v);
  if (v === 0) return '0';
  return Number.parseFloat(v.toPrecision(10)).toString();
}

/** "3000 rpm". */
export function engValueText(v: number, unit: string | null | undefined): string {
  return unit ? `${engNumberText(v)} ${unit}` : engNumberText(v);
}

/** "491520 raw (inc/s)". */
export function rawValueText(raw: number, rawUnit: string | null | undefined): string {
  const r = Number.isInteger(raw) ? raw.toString() : engNumberText(raw);
  return rawUnit ? `${r} raw (${rawUnit})` : `${r} raw`;
}

/**
 * The raw value in engineering units, as the input shows it: the shortest text (ten
 * significant digits or more) that converts back to the same raw value, so that writing
 * what is shown writes what the drive holds.
 */
export function rawToEngText(raw: number, spec: Pick<UnitSpec, 'scale' | 'data_type'>): string {
  const eng = raw * spec.scale;
  if (!Number.isFinite(eng) || eng === 0 || !isIntegerType(spec.data_type)) return engNumberText(eng);
  for (let digits = 10; digits < 17; digits++) {
    const text = Number.parseFloat(eng.toPrecision(digits)).toString();
    if (toRaw(spec, Number(text)).raw === raw) return text;
  }
  return eng.toString();
}

const NUMBER = /^[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?$/i;

export type EngParse = { ok: true; value: number } | { ok: false; message: string };

/** A typed decimal number (1500, -2.5, .5, 1e3); spaces and _ as digit grouping are allowed. */
export function parseEngineering(text: string): EngParse {
  const t = text.trim().replace(/[_\s]/g, '');
  if (t === '') return { ok: false, message: 'enter a value' };
  if (!NUMBER.test(t)) return { ok: false, message: `"${text.trim()}" is not a number` };
  const v = Number(t);
  if (!Number.isFinite(v)) return { ok: false, message: `"${text.trim()}" is too large` };
  return { ok: true, value: v };
}

/** Round half away from zero (-2.5 -> -3), as a person rounds; never -0. */
function roundHalfAway(x: number): number {
  const r = Math.sign(x) * Math.round(Math.abs(x));
  return r === 0 ? 0 : r;
}

export interface RawOf {
  raw: number;
  /** The raw value is not exactly the typed one: what it means in engineering units. */
  rounded: boolean;
}

/** raw = engineering / scale; whole for an integer object. No range check. */
export function toRaw(spec: Pick<UnitSpec, 'scale' | 'data_type'>, eng: number): RawOf {
  const exact = eng / spec.scale;
  if (!isIntegerType(spec.data_type)) return { raw: exact, rounded: false };
  const raw = roundHalfAway(exact);
  // eng / scale carries float noise (0.3 / 0.1 is 2.9999999999999996): a difference below
  // a billionth of the value is that noise, not a rounding the person should hear about.
  const rounded = Math.abs(exact - raw) > 1e-9 * Math.max(1, Math.abs(exact));
  return { raw, rounded };
}

/** "0 .. 1966080 rpm (0 .. 4294967295 inc/s)": the allowed raw range in both units. */
export function bothRangesText(spec: UnitSpec): string {
  const [lo, hi] = allowedRange(spec);
  if (lo === null && hi === null) return '';
  const a = lo === null ? null : lo * spec.scale;
  const b = hi === null ? null : hi * spec.scale;
  // A negative scale turns the range round.
  const [elo, ehi] = spec.scale < 0 ? [b, a] : [a, b];
  const e = `${elo === null ? '…' : engNumberText(elo)} .. ${ehi === null ? '…' : engNumberText(ehi)}${spec.unit ? ` ${spec.unit}` : ''}`;
  const r = `${lo === null ? '…' : lo} .. ${hi === null ? '…' : hi}${spec.raw_unit ? ` ${spec.raw_unit}` : ' raw'}`;
  return `${e} (${r})`;
}

export type EngEntry =
  | {
      ok: true;
      /** What is sent. */
      raw: number;
      /** What was typed. */
      typed: number;
      /** What the raw value means: raw × scale. */
      engineering: number;
      rounded: boolean;
      /** "3000 rpm = 491520 raw (inc/s)". */
      preview: string;
      /** "rounded to 491521 raw = 3000.006104 rpm (the drive takes whole inc/s)", or null. */
      note: string | null;
    }
  | { ok: false; message: string; hint: string | null };

/**
 * What a person typed in engineering units, as the raw value to send: parsed, converted,
 * rounded for an integer object, and refused when outside the object's range (the profile's
 * min/max inside the data type's), with the range in both units.
 */
export function engineeringToRaw(spec: UnitSpec, text: string): EngEntry {
  const unit = spec.unit ?? '';
  const parsed = parseEngineering(text);
  const range = bothRangesText(spec);
  if (!parsed.ok) {
    return {
      ok: false,
      message: parsed.message,
      hint: `a decimal number in ${unit || 'engineering units'}, e.g. 1500 or 2.5${range ? `; allowed ${range}` : ''}`,
    };
  }
  const typed = parsed.value;
  const { raw, rounded } = toRaw(spec, typed);
  const [lo, hi] = allowedRange(spec);
  const typedText = engValueText(typed, unit);
  if (lo !== null && raw < lo) {
    return { ok: false, message: `${typedText} (${rawValueText(raw, spec.raw_unit)}) is below the minimum: allowed ${range}`, hint: null };
  }
  if (hi !== null && raw > hi) {
    return { ok: false, message: `${typedText} (${rawValueText(raw, spec.raw_unit)}) is above the maximum: allowed ${range}`, hint: null };
  }
  if (isIntegerType(spec.data_type) && !Number.isSafeInteger(raw)) {
    return { ok: false, message: `${typedText} is ${raw} raw, too large to send as a JSON number`, hint: 'enter it raw, as bytes' };
  }
  if (/^REAL32$/i.test(spec.data_type) && Math.abs(raw) > REAL32_MAX) {
    return { ok: false, message: `${typedText} is beyond REAL32`, hint: null };
  }
  const engineering = raw * spec.scale;
  const why = spec.raw_unit ? `the drive takes whole ${spec.raw_unit}` : 'the drive takes whole raw steps';
  return {
    ok: true,
    raw,
    typed,
    engineering,
    rounded,
    preview: `${typedText} = ${rawValueText(raw, spec.raw_unit)}`,
    note: rounded ? `rounded to ${raw} raw = ${engValueText(engineering, unit)} (${why})` : null,
  };
}

/** The unit a value in an entry box was typed (or read) in, and for which address. */
export interface TypedIn {
  /** The engineering unit, or null: raw. */
  unit: string | null;
  address: string;
}

/**
 * Why a typed value cannot be used for the address now in the box (Object access), or null:
 * its number is in another unit than the one this address is entered in (`unitNow`, null:
 * raw). A number in the same unit stays valid whatever the new object's scale: 3000 rpm is
 * 3000 rpm for 6081h and 607Fh alike, its raw value is worked out with the new scale. One in
 * another unit means nothing there (3000 rpm is no 3000 deg, nor 3000 raw): it is held with
 * this note rather than read again in the new unit or converted with the new scale.
 */
export function heldValueNote(text: string, typed: TypedIn, unitNow: string | null, addressNow: string, rawUnitNow: string | null): string | null {
  if (text.trim() === '' || typed.unit === unitNow) return null;
  const value = `“${text.trim()}” ${typed.unit !== null ? `is in ${typed.unit}` : 'is a raw value'} (for ${typed.address})`;
  const here = addressNow || 'this address';
  if (unitNow === null) return `${value}; ${here} takes raw values: type the raw value.`;
  if (typed.unit === null) return `${value}; ${here} is entered in ${unitNow}: type it in ${unitNow}, or choose raw${rawUnitNow ? ` (${rawUnitNow})` : ''}.`;
  return `${value}; ${here} is entered in ${unitNow}: type the value in ${unitNow}.`;
}
