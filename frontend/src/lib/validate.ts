/**
 * Browser-side validation of a value before it is written (DESIGN.md: "every write is
 * validated against the profile before it reaches the bus"): the data type's range, the
 * profile's min/max, and the enumeration. It mirrors the backend's check_value so a person
 * sees the message in place instead of a round trip, and the backend still checks again.
 *
 * Enumerations: most `values` lists in the profiles describe values (some are bit meanings or
 * read-only states, e.g. 1010h:01 "saving in progress"), so an unlisted value only gets a
 * note. The CiA 402-2 objects whose list is closed (6060h modes of operation, 6098h homing
 * method) refuse an unlisted value, as the backend and the drive do.
 */
import type { ObjectInfo, ObjectScalar, ObjectWrite } from '../api/types';
import {
  type NumberMode,
  isBytesType,
  isIntegerType,
  isRealType,
  isStringType,
  parseNumberInput,
  toHex,
  typeRange,
} from './format';

/** CiA 402-2: modes of operation (6060h) and homing method (6098h) take listed values only. */
const CLOSED_ENUMS: ReadonlySet<number> = new Set([0x6060, 0x6098]);

export type WriteCheck =
  | { ok: true; body: ObjectWrite; value: ObjectScalar | null; note: string | null }
  | { ok: false; message: string; hint: string | null };

type Spec = Pick<ObjectInfo, 'index' | 'data_type' | 'access' | 'min' | 'max' | 'values' | 'raw_unit' | 'name'>;

function fmtLimit(v: number, spec: Spec, mode: NumberMode): string {
  if (mode === 'hex' && Number.isInteger(v) && isIntegerType(spec.data_type)) return `${v} (${toHex(v, spec.data_type)})`;
  return String(v);
}

/** The range a person may enter: the profile's limits inside the type's range. */
export function allowedRange(spec: Spec): [number | null, number | null] {
  const tr = typeRange(spec.data_type);
  let lo: number | null = tr ? Number(tr[0]) : null;
  let hi: number | null = tr ? Number(tr[1]) : null;
  if (spec.min !== null && spec.min !== undefined) lo = lo === null ? spec.min : Math.max(lo, spec.min);
  if (spec.max !== null && spec.max !== undefined) hi = hi === null ? spec.max : Math.min(hi, spec.max);
  return [lo, hi];
}

/**
 * "0 .. 20000 ms"; with `profileOnly`, empty when the profile gives no limits of its own;
 * with `withUnit` false, without the raw unit (for a table that has a unit column).
 */
export function rangeText(spec: Spec, mode: NumberMode = 'dec', profileOnly = false, withUnit = true): string {
  if (profileOnly && (spec.min === null || spec.min === undefined) && (spec.max === null || spec.max === undefined)) return '';
  const [lo, hi] = allowedRange(spec);
  if (lo === null && hi === null) return '';
  const unit = spec.raw_unit && withUnit ? ` ${spec.raw_unit}` : '';
  return `${lo === null ? '…' : fmtLimit(lo, spec, mode)} .. ${hi === null ? '…' : fmtLimit(hi, spec, mode)}${unit}`;
}

export function checkWrite(spec: Spec, text: string, mode: NumberMode): WriteCheck {
  if (!/w/i.test(spec.access)) {
    return { ok: false, message: `${spec.name} is ${spec.access === 'const' ? 'constant' : 'read-only'}`, hint: 'choose a writable object' };
  }
  const dt = spec.data_type;
  if (isStringType(dt)) return { ok: true, body: { value: text }, value: text, note: null };
  if (isBytesType(dt)) {
    const hex = text.replace(/[\s_]|0x/gi, '');
    if (!/^([0-9a-f]{2})*$/i.test(hex)) {
      return { ok: false, message: `"${text}" is not a byte string`, hint: 'enter bytes in bus order as hex pairs, e.g. 01 02 0A' };
    }
    return { ok: true, body: { raw_hex: hex.toLowerCase() }, value: hex.toLowerCase(), note: null };
  }
  const parsed = parseNumberInput(text, mode, dt);
  if (!parsed.ok) {
    return {
      ok: false,
      message: parsed.message,
      hint: mode === 'hex' ? 'digits 0-9 and A-F; switch to Dec for decimal input' : 'a whole number in the type’s range; switch to Hex for hexadecimal input',
    };
  }
  const v = parsed.value;
  const unit = spec.raw_unit ? ` ${spec.raw_unit}` : '';
  const range = rangeText(spec, mode);
  if (spec.min !== null && spec.min !== undefined && v < spec.min) {
    return { ok: false, message: `${v}${unit} is below the minimum ${spec.min}${unit}`, hint: `allowed range ${range}` };
  }
  if (spec.max !== null && spec.max !== undefined && v > spec.max) {
    return { ok: false, message: `${v}${unit} is above the maximum ${spec.max}${unit}`, hint: `allowed range ${range}` };
  }
  let note: string | null = null;
  if (spec.values && !isRealType(dt) && Object.keys(spec.values).length > 0 && !(String(v) in spec.values)) {
    const allowed = Object.entries(spec.values)
      .sort((a, b) => Number(a[0]) - Number(b[0]))
      .map(([k, t]) => `${k} (${t})`)
      .join(', ');
    if (CLOSED_ENUMS.has(spec.index)) {
      return { ok: false, message: `${v} is not an allowed value`, hint: `allowed: ${allowed}` };
    }
    note = `${v} is not one of the documented values`;
  }
  return { ok: true, body: { value: v }, value: v, note };
}
