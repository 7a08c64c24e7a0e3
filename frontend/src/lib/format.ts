/**
 * Value formatting and parsing for object values: decimal and hex side by side (the LECSN
 * card web server takes parameter values in hex, manual §20.7), raw little-endian bytes as
 * the bus carries them (CiA 301 §7.1.2), and engineering values with their unit.
 */

const BITS: Record<string, number> = {
  BOOLEAN: 1,
  INTEGER8: 8,
  INTEGER16: 16,
  INTEGER24: 24,
  INTEGER32: 32,
  INTEGER40: 40,
  INTEGER48: 48,
  INTEGER56: 56,
  INTEGER64: 64,
  UNSIGNED8: 8,
  UNSIGNED16: 16,
  UNSIGNED24: 24,
  UNSIGNED32: 32,
  UNSIGNED40: 40,
  UNSIGNED48: 48,
  UNSIGNED56: 56,
  UNSIGNED64: 64,
  REAL32: 32,
  REAL64: 64,
};

export function typeBits(dataType: string | null | undefined): number | null {
  return dataType ? (BITS[dataType.toUpperCase()] ?? null) : null;
}

export function isSignedType(dataType: string | null | undefined): boolean {
  return !!dataType && /^INTEGER\d+$/i.test(dataType);
}

export function isIntegerType(dataType: string | null | undefined): boolean {
  return !!dataType && /^(INTEGER|UNSIGNED)\d+$|^BOOLEAN$/i.test(dataType);
}

export function isRealType(dataType: string | null | undefined): boolean {
  return !!dataType && /^REAL(32|64)$/i.test(dataType);
}

export function isStringType(dataType: string | null | undefined): boolean {
  return !!dataType && /^(VISIBLE|UNICODE)_STRING$/i.test(dataType);
}

export function isBytesType(dataType: string | null | undefined): boolean {
  return !!dataType && /^(OCTET_STRING|DOMAIN)$/i.test(dataType);
}

/** The integer range a type holds, as bigints, or null for non-integers. */
export function typeRange(dataType: string | null | undefined): [bigint, bigint] | null {
  if (!isIntegerType(dataType)) return null;
  const bits = typeBits(dataType) ?? 0;
  if (bits === 1) return [0n, 1n];
  const b = BigInt(bits);
  return isSignedType(dataType) ? [-(1n << (b - 1n)), (1n << (b - 1n)) - 1n] : [0n, (1n << b) - 1n];
}

/**
 * Hex text of an integer, padded to the type's width; negative values of a signed type are
 * shown as the two's complement the drive holds (-1 as INTEGER16 is 0xFFFF).
 */
export function toHex(value: number | bigint, dataType?: string | null): string {
  let v: bigint;
  if (typeof value === 'bigint') v = value;
  else if (Number.isInteger(value)) v = BigInt(value);
  else return '—';
  const bits = typeBits(dataType);
  const width = bits && bits >= 8 ? bits : 8;
  if (v < 0n) {
    const w = BigInt(bits && bits >= 8 ? bits : 64);
    v = (1n << w) + v;
  }
  const digits = Math.max(2, Math.ceil(width / 4));
  return `0x${v.toString(16).toUpperCase().padStart(digits, '0')}`;
}

/** Decimal text with thin grouping for long integers (readable, still copy-pasteable). */
export function toDec(value: number | bigint): string {
  if (typeof value === 'number' && !Number.isInteger(value)) return formatReal(value);
  return value.toString();
}

export function formatReal(value: number, digits = 6): string {
  if (!Number.isFinite(value)) return String(value);
  if (value === 0) return '0';
  const abs = Math.abs(value);
  if (abs >= 1e9 || abs < 1e-4) return value.toExponential(digits - 1);
  // Six significant digits without trailing zeros.
  return Number.parseFloat(value.toPrecision(digits)).toString();
}

/** An engineering value with its unit, e.g. "12.5 rpm". */
export function formatEngineering(value: number | null | undefined, unit: string | null | undefined): string {
  if (value === null || value === undefined) return '—';
  const text = Number.isInteger(value) ? value.toString() : formatFixed(value);
  return unit ? `${text} ${unit}` : text;
}

function formatFixed(value: number): string {
  const abs = Math.abs(value);
  const decimals = abs >= 1000 ? 1 : abs >= 1 ? 3 : 4;
  return value.toFixed(decimals);
}

/** "e8030000" -> "E8 03 00 00" (bus order, little-endian). */
export function formatRawBytes(rawHex: string | null | undefined): string {
  if (!rawHex) return '—';
  const clean = rawHex.replace(/[^0-9a-f]/gi, '').toUpperCase();
  const pairs = clean.match(/.{1,2}/g);
  return pairs ? pairs.join(' ') : '—';
}

export type NumberMode = 'dec' | 'hex';

export type ValueParse<T> = { ok: true; value: T } | { ok: false; message: string };

/**
 * Parse what a person typed into the value box.
 *
 * In hex mode `3E8`, `0x3E8`, `3E8h` and `0000_03E8` all mean 1000; for a signed type a hex
 * value with the top bit set is read as two's complement (FFFF as INTEGER16 is -1), because
 * that is how the drive holds it. The result is range-checked against the data type.
 */
export function parseNumberInput(text: string, mode: NumberMode, dataType?: string | null): ValueParse<number> {
  const t = text.trim().replace(/[_\s]/g, '');
  if (t === '') return { ok: false, message: 'enter a value' };
  if (isRealType(dataType)) {
    if (mode === 'hex') return { ok: false, message: `${dataType} values are entered in decimal` };
    const f = Number(t);
    if (!Number.isFinite(f)) return { ok: false, message: `"${text.trim()}" is not a number` };
    return { ok: true, value: f };
  }
  let v: bigint;
  if (mode === 'hex') {
    const m = /^(-)?(?:0x)?([0-9a-f]+)h?$/i.exec(t);
    if (!m) return { ok: false, message: `"${text.trim()}" is not a hex number (digits 0-9, A-F)` };
    v = BigInt(`0x${m[2] ?? '0'}`);
    if (m[1]) v = -v;
    const bits = typeBits(dataType);
    if (!m[1] && bits && isSignedType(dataType)) {
      const b = BigInt(bits);
      if (v >= 1n << (b - 1n) && v < 1n << b) v -= 1n << b;
    }
  } else {
    if (/^-?0x[0-9a-f]+$/i.test(t)) return parseNumberInput(t, 'hex', dataType);
    if (!/^-?\d+$/.test(t)) {
      return {
        ok: false,
        message: dataType && !isIntegerType(dataType) ? `"${text.trim()}" is not a number` : `"${text.trim()}" is not a whole number`,
      };
    }
    v = BigInt(t);
  }
  const range = typeRange(dataType);
  if (range && (v < range[0] || v > range[1])) {
    return {
      ok: false,
      message: `${toDec(v)} is outside ${dataType} (${range[0].toString()}..${range[1].toString()})`,
    };
  }
  if (v > BigInt(Number.MAX_SAFE_INTEGER) || v < BigInt(Number.MIN_SAFE_INTEGER)) {
    return { ok: false, message: `${v.toString()} is too large to send as a JSON number; use raw bytes` };
  }
  return { ok: true, value: Number(v) };
}

/** Show a typed value in the chosen mode, for putting a read value back into the input box. */
export function valueToInput(value: unknown, mode: NumberMode, dataType?: string | null): string {
  if (typeof value === 'number') {
    if (mode === 'hex' && Number.isInteger(value)) return toHex(value, dataType).slice(2);
    return toDec(value);
  }
  if (typeof value === 'boolean') return value ? '1' : '0';
  if (typeof value === 'string') return value;
  return '';
}
