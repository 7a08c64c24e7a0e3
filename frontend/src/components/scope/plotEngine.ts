/**
 * The plot's decimation off the page's main thread: the messages between the page and the
 * plot worker (plot.worker.ts), and the worker's state, which is plain data and runs the same
 * in a unit test as in the worker.
 *
 * The worker holds its own copy of every stored sample the plot may show (the live samples
 * as they arrive, the capture or recording being shown) and answers a request for a window
 * with the min/max per pixel column of decimate.ts. The page keeps its samples too: the
 * measurements, the cursors and the trigger read them, and the exports are the server's
 * full-rate data, so nothing the worker does can lose a sample.
 */
import { DecimationCache, type PlotData, type PlotTrace, buildPlotData } from './decimate';
import { Series, share } from './series';

export type Store = 'live' | 'recording';

/** Page to worker. */
export type ToWorker =
  /** Samples to append to a live channel (times in backend seconds). */
  | { type: 'append'; id: number; t: Float64Array; v: Float64Array }
  /** Forget live channels (all when ids is null). */
  | { type: 'clear'; ids: number[] | null }
  /** The capture or recording shown now, replacing the previous one. */
  | { type: 'recording'; channels: { id: number; t: Float64Array; v: Float64Array }[] }
  | { type: 'plot'; request: PlotRequest };

/** One trace to draw: a stored channel, or samples sent with the request (a math channel). */
export type RequestTrace =
  | { kind: 'channel'; id: number; a: number; b: number; key: string }
  | { kind: 'inline'; t: Float64Array; v: Float64Array; n: number; a: number; b: number };

export interface PlotRequest {
  seq: number;
  store: Store;
  traces: (RequestTrace | null)[];
  origin: number;
  x0: number;
  x1: number;
  cols: number;
}

/** Worker to page: the aligned data, ys packed as Float64Arrays (NaN: no value there). */
export interface PlotReply {
  type: 'plot';
  seq: number;
  x: Float64Array;
  ys: Float64Array[];
  decimated: boolean;
  points: number;
  /** Decimated data's layout (decimate.ts PlotData). */
  off: number;
  count: number;
  window: [number, number];
}

/** PlotData's ys with NaN for null, in typed arrays (transferable, no per-value boxing). */
export function packYs(ys: readonly (number | null)[][]): Float64Array[] {
  return ys.map((y) => {
    const out = new Float64Array(y.length);
    for (let i = 0; i < y.length; i++) {
      const v = y[i];
      out[i] = v === null || v === undefined ? NaN : v;
    }
    return out;
  });
}

/** Back to uPlot's form: null where there is no value. */
export function unpackYs(ys: readonly Float64Array[]): (number | null)[][] {
  return ys.map((y) => {
    const out = new Array<number | null>(y.length);
    for (let i = 0; i < y.length; i++) {
      const v = y[i] as number;
      out[i] = Number.isNaN(v) ? null : v;
    }
    return out;
  });
}

/** The worker's state: copies of the samples, and the column cache of decimate.ts. */
export class PlotEngine {
  readonly live = new Map<number, Series>();
  recording = new Map<number, Series>();
  private readonly cache = new DecimationCache();
  private recordings = 0;

  /** Apply one message; a plot request is answered. */
  handle(msg: ToWorker): PlotReply | null {
    switch (msg.type) {
      case 'append': {
        let s = this.live.get(msg.id);
        if (!s) {
          s = new Series();
          this.live.set(msg.id, s);
          share(this.live);
        }
        s.append(0, 0, 0, msg.t, msg.v, Math.min(msg.t.length, msg.v.length));
        return null;
      }
      case 'clear':
        if (msg.ids === null) for (const s of this.live.values()) s.clear();
        else for (const id of msg.ids) this.live.get(id)?.clear();
        return null;
      case 'recording':
        this.recording = new Map(msg.channels.map((c) => [c.id, Series.of(c.t, c.v)]));
        this.recordings++;
        return null;
      case 'plot':
        return this.plot(msg.request);
    }
  }

  plot(r: PlotRequest): PlotReply {
    const store = r.store === 'live' ? this.live : this.recording;
    const traces = r.traces.map((d): PlotTrace | null => {
      if (!d) return null;
      if (d.kind === 'inline') return { t: d.t, v: d.v, n: d.n, a: d.a, b: d.b };
      const s = store.get(d.id);
      if (!s) return null;
      const generation = `${r.store === 'live' ? s.epoch : this.recordings}:${s.dropped}`;
      return { t: s.t, v: s.v, n: s.n, a: d.a, b: d.b, key: `${r.store}:${d.key}`, generation };
    });
    const data: PlotData = buildPlotData(traces, r.origin, r.x0, r.x1, r.cols, this.cache);
    return { type: 'plot', seq: r.seq, x: data.x, ys: packYs(data.ys), decimated: data.decimated, points: data.points, off: data.off ?? 0, count: data.count ?? 0, window: [r.x0, r.x1] };
  }
}
