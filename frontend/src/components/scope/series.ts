/**
 * One channel's samples in the browser: times (backend clock, s) and raw values in typed
 * arrays that grow in place (capacity doubles, so appending a frame costs its own length),
 * bounded so a scope left rolling for hours keeps a fixed amount of memory.
 *
 * Nothing here ever changes a stored value: display decimation and math work on views.
 */

/** Samples kept per channel while rolling: 2^19 is 131 s at 4 kHz, 8 MiB per channel. */
export const MAX_SAMPLES = 1 << 19;
/**
 * Samples all live channels keep together: 8 channels of MAX_SAMPLES (64 MiB of times and
 * values, as much again in the plot worker's copy). A scope of 8 channels keeps 131 s at 4 kHz
 * each as before; one of 32 keeps 33 s each rather than growing the tab to half a gigabyte.
 */
export const TOTAL_SAMPLES = 8 * MAX_SAMPLES;

/** What each of `channels` live series keeps within TOTAL_SAMPLES. */
export function perChannel(channels: number): number {
  return Math.floor(TOTAL_SAMPLES / Math.max(8, channels));
}

/** Give every series of `live` its share of TOTAL_SAMPLES (called when one is added). */
export function share(live: Map<number, Series>): void {
  const max = perChannel(live.size);
  for (const s of live.values()) s.max = max;
}

export class Series {
  t: Float64Array;
  v: Float64Array;
  n = 0;
  /** Samples dropped from the front to stay within `max`. */
  dropped = 0;
  /** Bumped by clear(): the same arrays then hold other samples. */
  epoch = 0;

  constructor(
    capacity = 1024,
    /** Samples kept at most; lowered by share() when more channels are live. */
    public max = MAX_SAMPLES,
  ) {
    this.t = new Float64Array(capacity);
    this.v = new Float64Array(capacity);
  }

  /** A series holding exactly these samples (a recording). */
  static of(t: ArrayLike<number>, v: ArrayLike<number>): Series {
    const n = Math.min(t.length, v.length);
    const s = new Series(Math.max(1, n), Math.max(MAX_SAMPLES, n));
    s.t.set(n === t.length ? t : Array.prototype.slice.call(t, 0, n));
    s.v.set(n === v.length ? v : Array.prototype.slice.call(v, 0, n));
    s.n = n;
    return s;
  }

  private reserve(extra: number): void {
    if (this.n + extra > this.max) {
      // Drop the oldest quarter (or what the new samples need) at once, so trimming is rare.
      const drop = Math.min(this.n, Math.max(this.n + extra - this.max, this.max >> 2));
      this.t.copyWithin(0, drop, this.n);
      this.v.copyWithin(0, drop, this.n);
      this.n -= drop;
      this.dropped += drop;
    }
    const need = this.n + extra;
    if (need <= this.t.length) return;
    let cap = this.t.length;
    while (cap < need) cap *= 2;
    const t = new Float64Array(cap);
    const v = new Float64Array(cap);
    t.set(this.t.subarray(0, this.n));
    v.set(this.v.subarray(0, this.n));
    this.t = t;
    this.v = v;
  }

  /**
   * Append `n` samples: times are `base + t0 + i * dt`, or `base + times[i]` when dt is 0.
   * Samples older than the last one held are left out (a time base never runs backwards).
   */
  append(base: number, t0: number, dt: number, times: ArrayLike<number> | null, values: ArrayLike<number>, n = values.length): void {
    if (n <= 0) return;
    this.reserve(Math.min(n, this.max));
    let last = this.n ? (this.t[this.n - 1] as number) : -Infinity;
    const start = n > this.max ? n - this.max : 0;
    for (let i = start; i < n; i++) {
      const ti = dt !== 0 || !times ? base + t0 + i * dt : base + (times[i] as number);
      if (!(ti > last)) continue;
      this.t[this.n] = ti;
      this.v[this.n] = values[i] as number;
      this.n++;
      last = ti;
    }
  }

  clear(): void {
    this.n = 0;
    this.dropped = 0;
    this.epoch++;
  }

  first(): number | null {
    return this.n ? (this.t[0] as number) : null;
  }

  last(): number | null {
    return this.n ? (this.t[this.n - 1] as number) : null;
  }
}

/** First index i in [0, n] with t[i] >= x (t ascending). */
export function lowerBound(t: Float64Array, n: number, x: number): number {
  let lo = 0;
  let hi = n;
  while (lo < hi) {
    const mid = (lo + hi) >>> 1;
    if ((t[mid] as number) < x) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

/** First index i in [0, n] with t[i] > x (t ascending). */
export function upperBound(t: Float64Array, n: number, x: number): number {
  let lo = 0;
  let hi = n;
  while (lo < hi) {
    const mid = (lo + hi) >>> 1;
    if ((t[mid] as number) <= x) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

/** Index of the sample nearest to x, or -1 when there is none. */
export function nearestIndex(t: Float64Array, n: number, x: number): number {
  if (n === 0) return -1;
  const i = lowerBound(t, n, x);
  if (i === 0) return 0;
  if (i >= n) return n - 1;
  return x - (t[i - 1] as number) <= (t[i] as number) - x ? i - 1 : i;
}
