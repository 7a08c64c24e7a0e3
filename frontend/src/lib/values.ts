/**
 * How a read value is shown on the Parameters and Object dictionary pages: raw decimal with
 * the raw unit, hex padded to the type's width (the card web server's entry base, LECSN manual
 * §20.7), and the engineering value (raw × scale) with the engineering unit.
 */
import type { ObjectInfo, ObjectScalar, ObjectValue } from '../api/types';
import { formatEngineering, isIntegerType, toDec, toHex } from './format';

export function decText(value: ObjectScalar | null | undefined): string {
  if (value === null || value === undefined) return '—';
  if (typeof value === 'number') return toDec(value);
  if (typeof value === 'boolean') return value ? '1' : '0';
  return value;
}

export function hexText(value: ObjectScalar | null | undefined, dataType: string | null | undefined): string {
  if (typeof value === 'number' && Number.isInteger(value) && isIntegerType(dataType)) return toHex(value, dataType);
  if (typeof value === 'boolean') return value ? '0x01' : '0x00';
  return '—';
}

/** Engineering value text with unit, or null when the object has no engineering unit. */
export function engineeringText(v: Pick<ObjectValue, 'engineering' | 'unit'> | null, o?: Pick<ObjectInfo, 'unit' | 'scale'>, value?: ObjectScalar | null): string | null {
  if (v && v.engineering !== null && v.unit) return formatEngineering(v.engineering, v.unit);
  if (o?.unit && typeof value === 'number') return formatEngineering(value * o.scale, o.unit);
  return null;
}

/** The engineering unit differs from the raw unit (else one unit column says it all). */
export function hasEngineering(o: Pick<ObjectInfo, 'unit' | 'scale' | 'raw_unit'>): boolean {
  return !!o.unit && (o.scale !== 1 || (o.raw_unit !== null && o.raw_unit !== o.unit));
}

export function enumText(o: Pick<ObjectInfo, 'values'>, value: ObjectScalar | null | undefined): string | null {
  if (!o.values || value === null || value === undefined) return null;
  const k = typeof value === 'boolean' ? (value ? '1' : '0') : String(value);
  return o.values[k] ?? null;
}

export function isObjectValue(x: unknown): x is ObjectValue {
  return !!x && typeof x === 'object' && 'raw_hex' in x && !('error' in x);
}
