/**
 * The data uPlot draws for one view: the traces' samples inside the visible window, on one
 * common x array (uPlot's aligned data), decimated for display only.
 *
 * When a trace has more samples in the window than the plot has pixel columns, each column
 * keeps the minimum and the maximum of its samples, in the order they occurred, so a spike
 * a single sample wide is still drawn; the stored samples are never changed. The columns are
 * anchored to the origin, so panning reuses the columns already computed. Otherwise the
 * samples are drawn at their own times (the traces' times merged, a trace without a sample
 * at a time is null there and uPlot spans the gap). One sample either side of the window
 * is kept so the lines reach the plot's edges.
 */
import { lowerBound, upperBound } from './series';

/** A trace to draw: its stored samples and the transform to the shown value (a * raw + b). */
export interface PlotTrace {
  t: Float64Array;
  v: Float64Array;
  n: number;
  a: number;
  b: number;
  /** Cache key (stored series only; a math channel computed per frame has none). */
  key?: string;
  /** Changes when stored samples were dropped or replaced (invalidates the cache). */
  generation?: string;
}

export interface PlotData {
  /** Seconds from the origin. */
  x: Float64Array;
  /** One array per trace, same length as x (null: no sample of this trace there). */
  ys: (number | null)[][];
  /** True when min/max per pixel column was used. */
  decimated: boolean;
  /** Stored samples inside the window, over all traces drawn. */
  points: number;
  /** Decimated: the slots of the samples left of the window (the columns start there), and the
   * number of columns (two slots each; the samples right of the window follow). */
  off?: number;
  count?: number;
}

interface Edge {
  x: number;
  trace: number;
  y: number;
}

/**
 * Column results kept between frames. The columns are anchored to the origin (column c holds
 * the samples with origin + c * w <= t < origin + (c + 1) * w), so while the user pans at one
 * zoom the columns stay the same and only those that come into view are computed; a column
 * is kept once a later sample exists (no new sample can fall into it any more).
 */
export class DecimationCache {
  readonly entries = new Map<string, ColumnCache>();

  clear(): void {
    this.entries.clear();
  }
}

interface ColumnCache {
  t: Float64Array;
  v: Float64Array;
  a: number;
  b: number;
  w: number;
  origin: number;
  generation: string;
  /** Column index of slot 0. */
  first: number;
  /** Per column: 0 not computed, 1 empty, 2 one value (lo), 3 lo then hi. */
  state: Uint8Array;
  lo: Float64Array;
  hi: Float64Array;
}

/**
 * Build the aligned data of `traces` (null: not drawn, an all-null column) for the window
 * [x0, x1] seconds from `origin`, for a plot `cols` pixel columns wide. With a cache, the
 * column results of the previous frames are reused (traces with a `key`).
 */
export function buildPlotData(
  traces: readonly (PlotTrace | null)[],
  origin: number,
  x0: number,
  x1: number,
  cols: number,
  cache?: DecimationCache,
): PlotData {
  cols = Math.max(1, Math.floor(cols));
  const a0 = origin + x0;
  const a1 = origin + x1;
  const ranges = traces.map((tr) => {
    if (!tr || tr.n === 0) return null;
    return { i0: lowerBound(tr.t, tr.n, a0), i1: upperBound(tr.t, tr.n, a1) };
  });
  let points = 0;
  let dense = false;
  for (const r of ranges) {
    if (!r) continue;
    points += r.i1 - r.i0;
    if (r.i1 - r.i0 > cols) dense = true;
  }
  if (!(x1 > x0)) dense = false;
  return dense ? decimated(traces, origin, x0, x1, cols, points, cache) : merged(traces, ranges, origin, points);
}

function decimated(
  traces: readonly (PlotTrace | null)[],
  origin: number,
  x0: number,
  x1: number,
  cols: number,
  points: number,
  cache: DecimationCache | undefined,
): PlotData {
  // The column width, rounded so that panning (x0 and x1 moved by the same dx, whose float
  // rounding differs in the last bits) keeps the same columns.
  const w = Number(((x1 - x0) / cols).toPrecision(10));
  // Columns anchored to the origin, covering the window.
  const cA = Math.floor(x0 / w);
  const cB = Math.max(cA + 1, Math.ceil(x1 / w));
  const count = cB - cA;
  const left: Edge[] = [];
  const right: Edge[] = [];
  const spans = traces.map((tr, k) => {
    if (!tr || tr.n === 0) return null;
    const iA = lowerBound(tr.t, tr.n, origin + cA * w);
    const iB = lowerBound(tr.t, tr.n, origin + cB * w);
    if (iA > 0) left.push({ x: (tr.t[iA - 1] as number) - origin, trace: k, y: tr.a * (tr.v[iA - 1] as number) + tr.b });
    if (iB < tr.n) right.push({ x: (tr.t[iB] as number) - origin, trace: k, y: tr.a * (tr.v[iB] as number) + tr.b });
    return { iA, iB };
  });
  left.sort((p, q) => p.x - q.x);
  right.sort((p, q) => p.x - q.x);
  const off = left.length;
  const len = off + 2 * count + right.length;
  const x = new Float64Array(len);
  left.forEach((e, i) => (x[i] = e.x));
  for (let c = 0; c < count; c++) {
    x[off + 2 * c] = (cA + c + 0.25) * w;
    x[off + 2 * c + 1] = (cA + c + 0.75) * w;
  }
  right.forEach((e, i) => (x[off + 2 * count + i] = e.x));

  const ys: (number | null)[][] = traces.map(() => new Array<number | null>(len).fill(null));
  left.forEach((e, i) => ((ys[e.trace] as (number | null)[])[i] = e.y));
  right.forEach((e, i) => ((ys[e.trace] as (number | null)[])[off + 2 * count + i] = e.y));

  const used = new Set<string>();
  for (let k = 0; k < traces.length; k++) {
    const tr = traces[k];
    const sp = spans[k];
    if (!tr || !sp) continue;
    let entry: ColumnCache | null = null;
    if (cache && tr.key !== undefined) {
      used.add(tr.key);
      entry = columnCache(cache, tr, origin, w, cA, count);
    }
    columnsMinMax(tr, sp.iA, sp.iB, origin, w, cA, count, ys[k] as (number | null)[], off, entry);
  }
  if (cache) for (const key of [...cache.entries.keys()]) if (!used.has(key)) cache.entries.delete(key);
  return { x, ys, decimated: true, points, off, count };
}

/** The cache entry of a trace for columns [cA, cA + count), re-based and checked. */
function columnCache(cache: DecimationCache, tr: PlotTrace, origin: number, w: number, cA: number, count: number): ColumnCache {
  const key = tr.key as string;
  const old = cache.entries.get(key);
  const entry: ColumnCache = {
    t: tr.t,
    v: tr.v,
    a: tr.a,
    b: tr.b,
    w,
    origin,
    generation: tr.generation ?? '',
    first: cA,
    state: new Uint8Array(count),
    lo: new Float64Array(count),
    hi: new Float64Array(count),
  };
  const same =
    old &&
    old.t === tr.t &&
    old.v === tr.v &&
    old.a === tr.a &&
    old.b === tr.b &&
    old.w === w &&
    old.origin === origin &&
    old.generation === (tr.generation ?? '');
  if (same) {
    // Copy the columns both cover.
    const from = Math.max(cA, old.first);
    const to = Math.min(cA + count, old.first + old.state.length);
    for (let c = from; c < to; c++) {
      const i = c - old.first;
      const j = c - cA;
      entry.state[j] = old.state[i] as number;
      entry.lo[j] = old.lo[i] as number;
      entry.hi[j] = old.hi[i] as number;
    }
  }
  cache.entries.set(key, entry);
  return entry;
}

/** First index in [from, to] with t >= x, searching forward from `from` (galloping). */
function advance(t: Float64Array, from: number, to: number, x: number): number {
  let lo = from;
  let hi = from;
  let step = 1;
  while (hi < to && (t[hi] as number) < x) {
    lo = hi + 1;
    hi = Math.min(to, hi + step);
    step *= 2;
  }
  while (lo < hi) {
    const mid = (lo + hi) >>> 1;
    if ((t[mid] as number) < x) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

/**
 * Min and max of each column [cA, cA + count) into y (two slots per column from `off`, in the
 * order they occurred). Samples [iA, iB) are those of these columns. Columns the cache holds
 * are taken from it; a column is cached once a sample after its end exists.
 */
function columnsMinMax(
  tr: PlotTrace,
  iA: number,
  iB: number,
  origin: number,
  w: number,
  cA: number,
  count: number,
  y: (number | null)[],
  off: number,
  entry: ColumnCache | null,
): void {
  const { t, v, a, b, n } = tr;
  const lastT = n ? (t[n - 1] as number) : -Infinity;
  let i = iA;
  let known = -1; // Index i is the start of column `known` (or not known).
  for (let c = 0; c < count; c++) {
    const at = off + 2 * c;
    const end = origin + (cA + c + 1) * w;
    if (entry) {
      const st = entry.state[c] as number;
      if (st !== 0) {
        if (st >= 2) y[at] = entry.lo[c] as number;
        if (st === 3) y[at + 1] = entry.hi[c] as number;
        continue;
      }
    }
    if (known !== c) i = advance(t, iA, iB, origin + (cA + c) * w);
    const stop = c === count - 1 ? iB : advance(t, i, iB, end);
    known = c + 1;
    if (stop <= i) {
      if (entry && lastT >= end) entry.state[c] = 1;
      i = stop;
      continue;
    }
    let mn = v[i] as number;
    let mx = mn;
    let imn = i;
    let imx = i;
    for (let k = i + 1; k < stop; k++) {
      const val = v[k] as number;
      if (val < mn) {
        mn = val;
        imn = k;
      } else if (val > mx) {
        mx = val;
        imx = k;
      }
    }
    let first = a * mn + b;
    let second: number | null = null;
    if (imn < imx) second = a * mx + b;
    else if (imx < imn) {
      first = a * mx + b;
      second = a * mn + b;
    }
    y[at] = first;
    if (second !== null) y[at + 1] = second;
    if (entry && lastT >= end) {
      entry.state[c] = second === null ? 2 : 3;
      entry.lo[c] = first;
      if (second !== null) entry.hi[c] = second;
    }
    i = stop;
  }
}

function merged(
  traces: readonly (PlotTrace | null)[],
  ranges: readonly ({ i0: number; i1: number } | null)[],
  origin: number,
  points: number,
): PlotData {
  // The window's samples plus one either side, per trace.
  const spans = traces.map((tr, k) => {
    const r = ranges[k];
    if (!tr || !r) return null;
    return { from: Math.max(0, r.i0 - 1), to: Math.min(tr.n, r.i1 + 1) };
  });
  let total = 0;
  for (const s of spans) if (s) total += s.to - s.from;
  const all = new Float64Array(total);
  let p = 0;
  traces.forEach((tr, k) => {
    const s = spans[k];
    if (!tr || !s) return;
    all.set(tr.t.subarray(s.from, s.to), p);
    p += s.to - s.from;
  });
  all.sort();
  // Unique times.
  let u = 0;
  for (let i = 0; i < all.length; i++) if (i === 0 || all[i] !== all[u - 1]) all[u++] = all[i] as number;
  const times = all.subarray(0, u);
  const x = new Float64Array(u);
  for (let i = 0; i < u; i++) x[i] = (times[i] as number) - origin;
  const ys: (number | null)[][] = traces.map(() => new Array<number | null>(u).fill(null));
  traces.forEach((tr, k) => {
    const s = spans[k];
    if (!tr || !s) return;
    const y = ys[k] as (number | null)[];
    let j = 0;
    for (let i = s.from; i < s.to; i++) {
      const ti = tr.t[i] as number;
      while (j < u && (times[j] as number) < ti) j++;
      if (j < u && times[j] === ti) y[j] = tr.a * (tr.v[i] as number) + tr.b;
    }
  });
  return { x, ys, decimated: false, points };
}
