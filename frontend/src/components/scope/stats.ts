/**
 * Measurements of the visible range and the cursors, computed from the stored samples (never
 * from the decimated drawing): min, max, mean, RMS, frequency, sample count and rate, the
 * same definitions as the backend's `servodesk.domain.scope.stats` (docs/scope.md "Pure
 * core"): the frequency counts crossings of the mean.
 */
import { lowerBound, nearestIndex, upperBound } from './series';

export interface Stats {
  n: number;
  min: number | null;
  max: number | null;
  mean: number | null;
  rms: number | null;
  /** From the crossings of the mean; null with fewer than three crossings. */
  freqHz: number | null;
  /** Samples per second over the range; null with fewer than two samples. */
  rateHz: number | null;
}

export const EMPTY_STATS: Stats = { n: 0, min: null, max: null, mean: null, rms: null, freqHz: null, rateHz: null };

/** Stats of samples [i0, i1) of (t, v) as stored. */
export function rangeStats(t: Float64Array, v: Float64Array, i0: number, i1: number): Stats {
  const n = i1 - i0;
  if (n <= 0) return EMPTY_STATS;
  let min = Infinity;
  let max = -Infinity;
  let sum = 0;
  let sumSq = 0;
  for (let i = i0; i < i1; i++) {
    const x = v[i] as number;
    if (x < min) min = x;
    if (x > max) max = x;
    sum += x;
    sumSq += x * x;
  }
  const mean = sum / n;
  // Crossings of the mean: a sample on the other side of the mean than the last sample that
  // was not on it. A sample exactly on the mean neither starts nor ends a half period.
  let crossings = 0;
  let firstCross = 0;
  let lastCross = 0;
  let side = 0;
  for (let i = i0; i < i1; i++) {
    const d = (v[i] as number) - mean;
    const s = d > 0 ? 1 : d < 0 ? -1 : 0;
    if (s === 0) continue;
    if (side !== 0 && s !== side) {
      const tc = t[i] as number;
      if (crossings === 0) firstCross = tc;
      lastCross = tc;
      crossings++;
    }
    side = s;
  }
  const span = (t[i1 - 1] as number) - (t[i0] as number);
  return {
    n,
    min,
    max,
    mean,
    rms: Math.sqrt(Math.max(0, sumSq / n)),
    freqHz: crossings >= 3 && lastCross > firstCross ? (crossings - 1) / 2 / (lastCross - firstCross) : null,
    rateHz: n >= 2 && span > 0 ? (n - 1) / span : null,
  };
}

/** Stats of the samples with times in [t0, t1]. */
export function windowStats(t: Float64Array, v: Float64Array, n: number, t0: number, t1: number): Stats {
  return rangeStats(t, v, lowerBound(t, n, t0), upperBound(t, n, t1));
}

/**
 * The stats of a * x + b from the stats of x. The mean, min and max follow the line (min and
 * max swap when a < 0); RMS from E[(ax+b)^2] = a^2 E[x^2] + 2ab E[x] + b^2; the frequency
 * and rate do not change.
 */
export function transformStats(s: Stats, a: number, b: number): Stats {
  if (s.n === 0 || s.min === null || s.max === null || s.mean === null || s.rms === null) return s;
  const lo = a * s.min + b;
  const hi = a * s.max + b;
  const meanSq = s.rms * s.rms;
  const rms2 = a * a * meanSq + 2 * a * b * s.mean + b * b;
  return { ...s, min: Math.min(lo, hi), max: Math.max(lo, hi), mean: a * s.mean + b, rms: Math.sqrt(Math.max(0, rms2)) };
}

/** The sample nearest to time x: its time and raw value, or null without samples. */
export function sampleAt(t: Float64Array, v: Float64Array, n: number, x: number): { t: number; v: number } | null {
  const i = nearestIndex(t, n, x);
  return i < 0 ? null : { t: t[i] as number, v: v[i] as number };
}

/** Delta-t between the cursors and its inverse (null when it is 0 or a cursor is missing). */
export function cursorDelta(a: number | null, b: number | null): { dt: number | null; inv: number | null } {
  if (a === null || b === null) return { dt: null, inv: null };
  const dt = b - a;
  return { dt, inv: dt !== 0 ? 1 / Math.abs(dt) : null };
}
