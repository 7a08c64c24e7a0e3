/** Number formats of the scope's readouts: significant digits, times and frequencies. */

/** `v` with `digits` significant digits, exponent form when very large or small; "—" for none. */
export function num(v: number | null | undefined, digits = 5): string {
  if (v === null || v === undefined || !Number.isFinite(v)) return '—';
  if (v === 0) return '0';
  const a = Math.abs(v);
  if (a >= 1e9 || a < 1e-4) return v.toExponential(digits - 1);
  if (Number.isInteger(v) && a < 1e9) return String(v);
  const s = v.toPrecision(digits);
  return s.includes('e') ? v.toExponential(digits - 1) : String(Number(s));
}

/** A duration in s, ms or µs. */
export function secs(v: number | null | undefined): string {
  if (v === null || v === undefined || !Number.isFinite(v)) return '—';
  const a = Math.abs(v);
  if (a !== 0 && a < 1e-3) return `${num(v * 1e6, 4)} µs`;
  if (a !== 0 && a < 1) return `${num(v * 1e3, 4)} ms`;
  return `${num(v, 6)} s`;
}

/** A frequency in Hz or kHz. */
export function hz(v: number | null | undefined): string {
  if (v === null || v === undefined || !Number.isFinite(v)) return '—';
  return Math.abs(v) >= 1000 ? `${num(v / 1000, 4)} kHz` : `${num(v, 4)} Hz`;
}

/** Value with its unit ("12.5 deg"), or just the value. */
export function withUnit(v: string, unit: string | null | undefined): string {
  return unit ? `${v} ${unit}` : v;
}
