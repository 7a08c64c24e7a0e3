/**
 * The page's side of the plot worker: keeps the worker's copy of the samples in step with the
 * model (only what is new is sent), asks it for the visible window's decimated data, one
 * request at a time, and hands the newest answer to the plot.
 *
 * One request in flight at most, and none while an answer waits to be drawn: while the
 * worker computes or the page has not drawn yet, the model may change many times (frames
 * arrive, the view scrolls, the user pans); the next request then asks for the state at that
 * moment. The plot is at most one answer behind, and the worker computes no more answers than
 * the page draws (on a busy machine it shares the cores with the page's main thread).
 */
import type { ScopeModel } from './model';
import type { PlotReply, RequestTrace, Store, ToWorker } from './plotEngine';
import type { Series } from './series';

/** What the worker was sent of one live series. */
interface Sent {
  series: Series;
  epoch: number;
  /** Samples of the series sent so far, counted from its first ever (dropped ones too). */
  upTo: number;
}

export interface WorkerLike {
  postMessage(msg: ToWorker, transfer: Transferable[]): void;
  onmessage: ((e: MessageEvent<PlotReply>) => void) | null;
  terminate(): void;
}

export class PlotFeed {
  private readonly sent = new Map<number, Sent>();
  private recording: Map<number, Series> | null = null;
  private seq = 0;
  private inFlight = false;
  private wanted = false;
  private cols = 0;
  /** The newest answer, not drawn yet (take() it). */
  latest: PlotReply | null = null;

  constructor(
    private readonly model: ScopeModel,
    private readonly worker: WorkerLike,
    private readonly onReply: () => void,
  ) {
    worker.onmessage = (e) => {
      this.inFlight = false;
      if (e.data.seq === this.seq) {
        this.latest = e.data;
        this.onReply();
      } else if (this.wanted) this.request(this.cols);
    };
  }

  /** The answer to draw now (null: none new); a change meanwhile is asked for at once. */
  take(): PlotReply | null {
    const r = this.latest;
    this.latest = null;
    if (this.wanted) this.request(this.cols);
    return r;
  }

  /** Send the worker what it lacks of the model's samples. */
  private sync(): void {
    const m = this.model;
    for (const [id, s] of m.live) {
      const had = this.sent.get(id);
      const total = s.dropped + s.n;
      let from: number;
      if (!had || had.series !== s || had.epoch !== s.epoch || had.upTo < s.dropped) {
        if (had) this.post({ type: 'clear', ids: [id] });
        from = 0;
      } else from = had.upTo - s.dropped;
      if (from < s.n) this.post({ type: 'append', id, t: s.t.slice(from, s.n), v: s.v.slice(from, s.n) });
      this.sent.set(id, { series: s, epoch: s.epoch, upTo: total });
    }
    if (m.kind !== 'live' && m.recording !== this.recording) {
      this.recording = m.recording;
      const channels = [...m.recording].map(([id, s]) => ({ id, t: s.t.slice(0, s.n), v: s.v.slice(0, s.n) }));
      this.post({ type: 'recording', channels });
    }
  }

  private post(msg: ToWorker): void {
    const transfer: Transferable[] = [];
    if (msg.type === 'append') transfer.push(msg.t.buffer, msg.v.buffer);
    else if (msg.type === 'recording') for (const c of msg.channels) transfer.push(c.t.buffer, c.v.buffer);
    else if (msg.type === 'plot') for (const d of msg.request.traces) if (d?.kind === 'inline') transfer.push(d.t.buffer, d.v.buffer);
    this.worker.postMessage(msg, transfer);
  }

  /** Ask for the current window, `cols` pixel columns wide (queued while one is in flight). */
  request(cols: number): void {
    this.cols = cols;
    if (this.inFlight || this.latest !== null) {
      this.wanted = true;
      return;
    }
    this.wanted = false;
    this.inFlight = true;
    this.sync();
    const m = this.model;
    const [x0, x1] = m.window();
    const o = m.origin;
    const traces = m.traces.map((d): RequestTrace | null => {
      if (!d.visible) return null;
      if (d.kind === 'channel') return { kind: 'channel', id: d.id, a: d.engScale * d.scale, b: d.offset, key: d.key };
      const s = m.mathSamples(d, o + x0, o + x1)?.shown;
      return s ? { kind: 'inline', t: s.t.slice(0, s.n), v: s.v.slice(0, s.n), n: s.n, a: 1, b: 0 } : null;
    });
    const store: Store = m.kind === 'live' ? 'live' : 'recording';
    this.post({ type: 'plot', request: { seq: ++this.seq, store, traces, origin: o, x0, x1, cols } });
  }

  dispose(): void {
    this.worker.onmessage = null;
    this.worker.terminate();
  }
}

/** The real worker (Vite bundles plot.worker.ts as a module worker). */
export function startPlotWorker(): WorkerLike {
  return new Worker(new URL('./plot.worker.ts', import.meta.url), { type: 'module', name: 'scope-plot' }) as unknown as WorkerLike;
}
