/**
 * Math channels, computed in the browser from the channels' samples (docs/scope.md "Math
 * channels"): `diff(a, b)` = a - b, `sum(a, b)` = a + b, `deriv(a)` = da/dt.
 *
 * Channels from different sources have different sample times: a two-channel result is given
 * at the first channel's times, with the second linearly interpolated between its own
 * samples, and only where the second has samples on both sides (no extrapolation: a value
 * the second channel never had is not invented). The derivative is the backward difference
 * (v[i] - v[i-1]) / (t[i] - t[i-1]) at t[i].
 */

export type MathOp = 'diff' | 'sum' | 'deriv';

export const MATH_OPS: readonly MathOp[] = ['diff', 'sum', 'deriv'];

export interface Samples {
  t: Float64Array;
  v: Float64Array;
  n: number;
}

export function needsSecond(op: MathOp): boolean {
  return op !== 'deriv';
}

/** The samples [i0, i1) of s as a * v + b (a copy; the stored samples stay as they are). */
export function transformed(s: Samples, a: number, b: number, i0 = 0, i1 = s.n): Samples {
  const n = Math.max(0, i1 - i0);
  const v = new Float64Array(n);
  for (let i = 0; i < n; i++) v[i] = a * (s.v[i0 + i] as number) + b;
  return { t: s.t.subarray(i0, i0 + n), v, n };
}

export function mathChannel(op: MathOp, a: Samples, b: Samples | null): Samples {
  if (op === 'deriv') {
    const n = Math.max(0, a.n - 1);
    const t = new Float64Array(n);
    const v = new Float64Array(n);
    let k = 0;
    for (let i = 1; i < a.n; i++) {
      const dt = (a.t[i] as number) - (a.t[i - 1] as number);
      if (!(dt > 0)) continue;
      t[k] = a.t[i] as number;
      v[k] = ((a.v[i] as number) - (a.v[i - 1] as number)) / dt;
      k++;
    }
    return { t: t.subarray(0, k), v: v.subarray(0, k), n: k };
  }
  if (!b || b.n === 0 || a.n === 0) return { t: new Float64Array(0), v: new Float64Array(0), n: 0 };
  const sign = op === 'diff' ? -1 : 1;
  const t = new Float64Array(a.n);
  const v = new Float64Array(a.n);
  const bFirst = b.t[0] as number;
  const bLast = b.t[b.n - 1] as number;
  let k = 0;
  let j = 0;
  for (let i = 0; i < a.n; i++) {
    const ti = a.t[i] as number;
    if (ti < bFirst || ti > bLast) continue;
    while (j < b.n - 1 && (b.t[j + 1] as number) <= ti) j++;
    const tj = b.t[j] as number;
    let bv = b.v[j] as number;
    if (tj !== ti && j < b.n - 1) {
      const tn = b.t[j + 1] as number;
      bv += ((b.v[j + 1] as number) - bv) * ((ti - tj) / (tn - tj));
    }
    t[k] = ti;
    v[k] = (a.v[i] as number) + sign * bv;
    k++;
  }
  return { t: t.subarray(0, k), v: v.subarray(0, k), n: k };
}

/** The unit of a math channel's result, from its operands' units. */
export function mathUnit(op: MathOp, unitA: string, unitB: string | null): string {
  if (op === 'deriv') return unitA ? `${unitA}/s` : '1/s';
  if (unitB !== null && unitB !== unitA) return `${unitA || '–'} ${op === 'diff' ? '−' : '+'} ${unitB || '–'}`;
  return unitA;
}

/** How a math channel is written in the legend, e.g. "Position − Demand". */
export function mathLabel(op: MathOp, a: string, b: string | null): string {
  if (op === 'deriv') return `d(${a})/dt`;
  return `${a} ${op === 'diff' ? '−' : '+'} ${b ?? '?'}`;
}
