/**
 * The scope's data and view in the browser, outside React: the stored samples of each channel
 * (raw values, backend time), what is shown (the live stream, the last capture or an imported
 * recording), the visible window (following the newest sample, or zoomed and panned by the
 * user), the two cursors, and the skipped-frame count the server reports.
 *
 * The plot redraws from it at most once per animation frame; the React panels read a summary
 * a few times a second. A value is shown as engineering = raw x the profile's scale, then the
 * channel's own scale and offset (shown = engineering x scale + offset).
 */
import { DecimationCache, type PlotData, type PlotTrace, buildPlotData } from './decimate';
import { type MathOp, type Samples, mathChannel, needsSecond, transformed } from './math';
import { Series, lowerBound, share, upperBound } from './series';
import { EMPTY_STATS, type Stats, rangeStats, sampleAt, transformStats } from './stats';
import { KIND_CAPTURE, KIND_SAMPLES, type ScopeFrame } from '../../scope/wire';

export type ViewKind = 'live' | 'capture' | 'recording';

/** One trace of the plot: a channel, or a math channel over channels. */
export interface TraceDef {
  /** "c3" for channel 3, "m0" for math channel 0. */
  key: string;
  kind: 'channel' | 'math';
  /** Channel id 0..31, or the math channel's number. */
  id: number;
  label: string;
  colour: string;
  visible: boolean;
  /** Unit of the shown (engineering) value. */
  unit: string;
  /** Unit of the raw value. */
  rawUnit: string;
  /** Raw to engineering (profile). */
  engScale: number;
  /** The channel's own display scale and offset. */
  scale: number;
  offset: number;
  /** Math channels: the operation and the operand channel ids. */
  op?: MathOp;
  a?: number;
  b?: number | null;
}

/** Measurements of one trace over the visible window, shown and raw. */
export interface TraceStats {
  key: string;
  shown: Stats;
  raw: Stats;
}

export interface CursorValue {
  key: string;
  /** Time of the sample used (s from the origin), shown value and raw value. */
  t: number;
  shown: number;
  raw: number;
}

/** A recording to open (capture or import), times in backend seconds. */
export interface OpenRecording {
  triggerTime: number | null;
  channels: { id: number; t: ArrayLike<number>; v: ArrayLike<number> }[];
  name?: string | null;
}

/** The window shown before the user zooms or pans, while live. */
export const DEFAULT_SPAN_S = 10;

export class ScopeModel {
  /** The live stream's samples per channel id. */
  readonly live = new Map<number, Series>();
  /** The capture or imported recording being shown. */
  recording = new Map<number, Series>();
  /** Last source byte seen per channel on the wire (1 pdo, 2 sdo, 3 recorder). */
  readonly wireSource = new Map<number, number>();
  traces: TraceDef[] = [];
  kind: ViewKind = 'live';
  recordingName: string | null = null;
  /** Backend time of x = 0: the first live sample, or the trigger of a capture. */
  liveOrigin: number | null = null;
  recordingOrigin = 0;
  triggerTime: number | null = null;
  /** Whether the scope runs (samples arriving): a stopped live view has a whole run to show. */
  running = true;
  /** Follow the newest sample with a window of `span` seconds, until the user zooms or pans. */
  follow = true;
  span = DEFAULT_SPAN_S;
  x0 = 0;
  x1 = DEFAULT_SPAN_S;
  /** Cursor times, seconds from the origin. */
  cursorA: number | null = null;
  cursorB: number | null = null;
  /** Frames the server skipped for this browser (cumulative, from the frame headers). */
  skipped = 0;
  /** True when the last frame said frames were skipped just before it. */
  skippedRecently = false;
  frames = 0;
  lastSeq: number | null = null;
  /** Bumped on every change of data or view; the plot and panels compare it. */
  version = 0;
  /** Draws done by the plot (the benchmark's frame count), and the time spent building them. */
  draws = 0;
  drawMs = 0;
  /**
   * Follow the live samples smoothly (issue 50): the window's right edge is a play-head that
   * advances with the wall clock every animation frame (tick), a little behind the newest
   * sample, instead of jumping to the newest sample when a frame arrives. The server sends a
   * few frames a second (the recorder's uploads, the stream's batching), so a view that moves
   * only with the data redraws only that often: 7-8 times a second with 8 channels of the
   * drive's recorder. Off: the former behaviour (`?plot=main`, the benchmark's baseline).
   */
  smooth = false;
  /** Wall clock in seconds (injected by the tests). */
  now: () => number = () => performance.now() / 1000;
  /** Backend time at the right edge while following smoothly (null: the newest sample). */
  private playhead: number | null = null;
  /** Newest sample's backend time minus the wall clock at its arrival (smoothed), seconds. */
  private lead: number | null = null;
  /** Smoothed interval between arrivals of live samples (s). */
  private arrivalGap = 0.1;
  private lastArrival: number | null = null;
  private readonly listeners = new Set<() => void>();
  private readonly columns = new DecimationCache();

  subscribe(fn: () => void): () => void {
    this.listeners.add(fn);
    return () => this.listeners.delete(fn);
  }

  changed(): void {
    this.version++;
    for (const l of this.listeners) l();
  }

  // ----------------------------------------------------------------------------------- data

  /**
   * Note a frame's header (every kind, status frames too: they take sequence numbers): the
   * skipped count the server reports for this client, and a gap in the numbers, which the
   * contract says never happens (skips are counted instead) but is counted rather than hidden.
   */
  noteFrame(frame: ScopeFrame): void {
    if (this.lastSeq !== null && frame.seq > this.lastSeq + 1) this.skipped += frame.seq - this.lastSeq - 1;
    this.lastSeq = frame.seq;
    this.skipped = Math.max(this.skipped, frame.skipped);
    this.skippedRecently = frame.skippedBefore;
  }

  /** Take one decoded frame of the stream: samples are appended, a capture is shown. */
  ingest(frame: ScopeFrame): void {
    this.noteFrame(frame);
    if (frame.kind !== KIND_SAMPLES && frame.kind !== KIND_CAPTURE) return;
    this.frames++;
    if (frame.kind === KIND_SAMPLES) {
      for (const b of frame.blocks) {
        let s = this.live.get(b.id);
        if (!s) {
          s = new Series();
          this.live.set(b.id, s);
          share(this.live);
        }
        this.wireSource.set(b.id, b.source);
        s.append(frame.tRef, b.t0, b.dt, b.dt > 0 ? null : b.times, b.values, b.n);
        if (this.liveOrigin === null && s.n) this.liveOrigin = s.t[0] as number;
      }
      this.noteArrival();
      this.changed();
    } else if (frame.kind === KIND_CAPTURE) {
      const channels = frame.blocks.map((b) => {
        const t = new Float64Array(b.n);
        for (let i = 0; i < b.n; i++) t[i] = frame.tRef + (b.times[i] as number);
        this.wireSource.set(b.id, b.source);
        return { id: b.id, t, v: b.values };
      });
      // The server sends a capture with t_ref at the trigger sample (services/scope.py).
      this.openRecording({ triggerTime: frame.tRef, channels }, 'capture');
    }
  }

  /** Time the arrival of live samples: how far the backend's newest sample leads the wall
   * clock, and how far apart the arrivals are. */
  private noteArrival(): void {
    let newest = -Infinity;
    for (const s of this.live.values()) if (s.n) newest = Math.max(newest, s.t[s.n - 1] as number);
    if (!Number.isFinite(newest)) return;
    const wall = this.now();
    if (this.lastArrival !== null) {
      const gap = Math.min(2, Math.max(0, wall - this.lastArrival));
      this.arrivalGap += (gap - this.arrivalGap) * 0.2;
    }
    this.lastArrival = wall;
    const lead = newest - wall;
    // A frame that came early (less delayed) sets the lead at once; late ones pull it slowly,
    // so the play-head runs at the wall clock's pace and does not jitter with the network.
    this.lead = this.lead === null || lead > this.lead ? lead : this.lead + (lead - this.lead) * 0.05;
  }

  /**
   * Move the smooth play-head to the wall clock's `wall` (seconds, default now); called every
   * animation frame by the plot. It stays behind the newest sample by about 1.5 arrival
   * intervals, so the right edge has data between two frames, never passes the newest sample,
   * and never runs backwards. True (and listeners told) when the view moved.
   */
  tick(wall = this.now()): boolean {
    if (!this.smooth || this.kind !== 'live' || !this.running || !this.follow || this.lead === null) return false;
    let newest = -Infinity;
    for (const s of this.live.values()) if (s.n) newest = Math.max(newest, s.t[s.n - 1] as number);
    if (!Number.isFinite(newest)) return false;
    let p = Math.min(newest, wall + this.lead - 1.5 * this.arrivalGap);
    if (this.playhead !== null) p = Math.max(p, this.playhead);
    if (p === this.playhead) return false;
    this.playhead = p;
    this.changed();
    return true;
  }

  /** Forget the live samples (new channels, or a new run). */
  clearLive(ids?: readonly number[]): void {
    this.playhead = null;
    this.lead = null;
    this.lastArrival = null;
    if (ids) for (const id of ids) this.live.get(id)?.clear();
    else for (const s of this.live.values()) s.clear();
    let first: number | null = null;
    for (const s of this.live.values()) {
      const f = s.first();
      if (f !== null && (first === null || f < first)) first = f;
    }
    this.liveOrigin = first;
    this.changed();
  }

  /** Show a capture or a recording; the view fits it, the trigger (if any) at x = 0. */
  openRecording(rec: OpenRecording, kind: 'capture' | 'recording'): void {
    const map = new Map<number, Series>();
    let first = Infinity;
    let last = -Infinity;
    for (const c of rec.channels) {
      const s = Series.of(c.t, c.v);
      map.set(c.id, s);
      if (s.n) {
        first = Math.min(first, s.t[0] as number);
        last = Math.max(last, s.t[s.n - 1] as number);
      }
    }
    this.recording = map;
    this.kind = kind;
    this.recordingName = rec.name ?? null;
    this.triggerTime = rec.triggerTime;
    this.recordingOrigin = rec.triggerTime ?? (Number.isFinite(first) ? first : 0);
    this.cursorA = null;
    this.cursorB = null;
    this.follow = false;
    if (Number.isFinite(first) && last > first) {
      this.x0 = first - this.recordingOrigin;
      this.x1 = last - this.recordingOrigin;
    } else {
      this.x0 = 0;
      this.x1 = 1;
    }
    this.changed();
  }

  /** Back to the live stream. */
  showLive(): void {
    this.kind = 'live';
    this.triggerTime = null;
    this.recordingName = null;
    this.cursorA = null;
    this.cursorB = null;
    this.follow = true;
    this.changed();
  }

  setTraces(traces: TraceDef[]): void {
    this.traces = traces;
    this.changed();
  }

  /** The series shown for channel `id`. */
  seriesOf(id: number): Series | undefined {
    return (this.kind === 'live' ? this.live : this.recording).get(id);
  }

  get origin(): number {
    return this.kind === 'live' ? (this.liveOrigin ?? 0) : this.recordingOrigin;
  }

  /** Newest sample shown, seconds from the origin (null without samples). */
  latest(): number | null {
    let last: number | null = null;
    for (const s of (this.kind === 'live' ? this.live : this.recording).values()) {
      const l = s.last();
      if (l !== null && (last === null || l > last)) last = l;
    }
    return last === null ? null : last - this.origin;
  }

  /** Oldest and newest sample shown, seconds from the origin. */
  extent(): [number, number] | null {
    let first = Infinity;
    let last = -Infinity;
    for (const s of (this.kind === 'live' ? this.live : this.recording).values()) {
      if (!s.n) continue;
      first = Math.min(first, s.t[0] as number);
      last = Math.max(last, s.t[s.n - 1] as number);
    }
    return Number.isFinite(first) ? [first - this.origin, last - this.origin] : null;
  }

  /** Total samples held in what is shown. */
  sampleCount(): number {
    let n = 0;
    for (const s of (this.kind === 'live' ? this.live : this.recording).values()) n += s.n;
    return n;
  }

  // ----------------------------------------------------------------------------------- view

  /** The visible window [x0, x1], seconds from the origin. */
  window(): [number, number] {
    if (this.kind === 'live' && this.follow) {
      const smooth = this.smooth && this.running && this.playhead !== null && this.liveOrigin !== null;
      const latest = smooth ? (this.playhead as number) - (this.liveOrigin as number) : this.latest();
      if (latest === null || latest < this.span) return [0, this.span];
      return [latest - this.span, latest];
    }
    return [this.x0, this.x1];
  }

  private fix(): void {
    const [x0, x1] = this.window();
    this.x0 = x0;
    this.x1 = x1;
    this.follow = false;
  }

  /** Move the window by dx seconds (positive: later). */
  pan(dx: number): void {
    this.fix();
    this.x0 += dx;
    this.x1 += dx;
    this.changed();
  }

  zoomTo(x0: number, x1: number): void {
    if (!(x1 > x0)) return;
    this.follow = false;
    this.x0 = x0;
    this.x1 = x1;
    this.changed();
  }

  /** Zoom by `factor` (> 1: wider) keeping time x where it is on screen. */
  zoomAround(x: number, factor: number): void {
    this.fix();
    const width = Math.max(1e-6, (this.x1 - this.x0) * factor);
    const frac = (x - this.x0) / (this.x1 - this.x0);
    this.x0 = x - frac * width;
    this.x1 = this.x0 + width;
    this.changed();
  }

  /** Running live: follow the newest sample again; stopped, or a capture or recording: show
   * all of it (after Stop the run is what the engineer looks at, not its last window). */
  resetZoom(): void {
    const e = this.kind === 'live' && this.running ? null : this.extent();
    if (e && e[1] > e[0]) {
      this.follow = false;
      [this.x0, this.x1] = e;
    } else if (this.kind === 'live') this.follow = true;
    this.changed();
  }

  /** The scope started or stopped (its status). */
  setRunning(running: boolean): void {
    if (running === this.running) return;
    this.running = running;
    this.changed();
  }

  setSpan(span: number): void {
    if (span > 0) this.span = span;
    this.changed();
  }

  setCursor(which: 'a' | 'b', x: number | null): void {
    if (which === 'a') this.cursorA = x;
    else this.cursorB = x;
    this.changed();
  }

  // ------------------------------------------------------------------------------ per trace

  private channelTrace(d: TraceDef): PlotTrace | null {
    const s = this.seriesOf(d.id);
    if (!s) return null;
    return { t: s.t, v: s.v, n: s.n, a: d.engScale * d.scale, b: d.offset, key: `${this.kind}:${d.key}`, generation: `${s.epoch}:${s.dropped}` };
  }

  /** A math channel's samples in backend time [t0, t1] (with one sample of margin), shown and raw. */
  mathSamples(d: TraceDef, t0: number, t1: number): { shown: Samples; raw: Samples } | null {
    if (d.op === undefined || d.a === undefined) return null;
    const defA = this.traces.find((x) => x.kind === 'channel' && x.id === d.a);
    const sa = this.seriesOf(d.a);
    if (!defA || !sa) return null;
    const slice = (s: Series, def: TraceDef, margin: number) => {
      const i0 = Math.max(0, lowerBound(s.t, s.n, t0) - margin);
      const i1 = Math.min(s.n, upperBound(s.t, s.n, t1) + margin);
      return {
        shown: transformed(s, def.engScale * def.scale, def.offset, i0, i1),
        raw: { t: s.t.subarray(i0, i1), v: s.v.subarray(i0, i1), n: i1 - i0 },
      };
    };
    const A = slice(sa, defA, 1);
    if (!needsSecond(d.op)) return { shown: mathChannel(d.op, A.shown, null), raw: mathChannel(d.op, A.raw, null) };
    if (d.b === undefined || d.b === null) return null;
    const defB = this.traces.find((x) => x.kind === 'channel' && x.id === d.b);
    const sb = this.seriesOf(d.b);
    if (!defB || !sb) return null;
    const B = slice(sb, defB, 2);
    return { shown: mathChannel(d.op, A.shown, B.shown), raw: mathChannel(d.op, A.raw, B.raw) };
  }

  private plotTrace(d: TraceDef, t0: number, t1: number): PlotTrace | null {
    if (!d.visible) return null;
    if (d.kind === 'channel') return this.channelTrace(d);
    const m = this.mathSamples(d, t0, t1);
    return m ? { ...m.shown, a: 1, b: 0 } : null;
  }

  /** What uPlot draws for the current window, `cols` pixel columns wide. */
  plotData(cols: number): PlotData & { window: [number, number] } {
    const [x0, x1] = this.window();
    const o = this.origin;
    const traces = this.traces.map((d) => this.plotTrace(d, o + x0, o + x1));
    return { ...buildPlotData(traces, o, x0, x1, cols, this.columns), window: [x0, x1] };
  }

  /** Min, max, mean, RMS, frequency of each trace over the visible window. */
  stats(): TraceStats[] {
    const [x0, x1] = this.window();
    const o = this.origin;
    return this.traces.map((d) => {
      if (d.kind === 'channel') {
        const s = this.seriesOf(d.id);
        if (!s) return { key: d.key, shown: EMPTY_STATS, raw: EMPTY_STATS };
        const raw = rangeStats(s.t, s.v, lowerBound(s.t, s.n, o + x0), upperBound(s.t, s.n, o + x1));
        return { key: d.key, shown: transformStats(raw, d.engScale * d.scale, d.offset), raw };
      }
      const m = this.mathSamples(d, o + x0, o + x1);
      if (!m) return { key: d.key, shown: EMPTY_STATS, raw: EMPTY_STATS };
      const inWindow = (x: Samples) => rangeStats(x.t, x.v, lowerBound(x.t, x.n, o + x0), upperBound(x.t, x.n, o + x1));
      return { key: d.key, shown: inWindow(m.shown), raw: inWindow(m.raw) };
    });
  }

  /** Each trace's sample nearest to cursor time x (s from the origin). */
  valuesAt(x: number): CursorValue[] {
    const o = this.origin;
    const out: CursorValue[] = [];
    for (const d of this.traces) {
      if (d.kind === 'channel') {
        const s = this.seriesOf(d.id);
        const p = s ? sampleAt(s.t, s.v, s.n, o + x) : null;
        if (p) out.push({ key: d.key, t: p.t - o, raw: p.v, shown: d.engScale * d.scale * p.v + d.offset });
        continue;
      }
      const m = this.mathSamples(d, o + x, o + x);
      const ps = m ? sampleAt(m.shown.t, m.shown.v, m.shown.n, o + x) : null;
      const pr = m ? sampleAt(m.raw.t, m.raw.v, m.raw.n, o + x) : null;
      if (ps && pr) out.push({ key: d.key, t: ps.t - o, shown: ps.v, raw: pr.v });
    }
    return out;
  }
}
