/**
 * The plot's worker path without a browser: the decimation the worker runs (PlotEngine, the
 * same code as plot.worker.ts), the page's feed of it (PlotFeed, with the engine behind a
 * worker-shaped object), and the column strokes (columns.ts).
 */
import { describe, expect, it } from 'vitest';
import { columnSegments } from './columns';
import { buildPlotData, type PlotTrace } from './decimate';
import { ScopeModel, type TraceDef } from './model';
import { PlotEngine, type PlotReply, type ToWorker, packYs, unpackYs } from './plotEngine';
import { PlotFeed, type WorkerLike } from './plotFeed';
import { KIND_SAMPLES, type ScopeFrame } from '../../scope/wire';

const RATE = 4000;

function trace(key: string, id: number): TraceDef {
  return { key, kind: 'channel', id, label: key, colour: '#000', visible: true, unit: 'deg', rawUnit: 'inc', engScale: 0.5, scale: 2, offset: 1 };
}

/** A samples frame of equidistant blocks (the decoder's output for wire kind 1). */
function frame(seq: number, tRef: number, blocks: { id: number; values: number[] }[]): ScopeFrame {
  return {
    version: 1,
    kind: KIND_SAMPLES,
    flags: 0,
    seq,
    skipped: 0,
    skippedBefore: false,
    tRef,
    status: null,
    blocks: blocks.map((b) => ({
      id: b.id,
      source: 1,
      sourceName: 'pdo' as const,
      n: b.values.length,
      dt: 1 / RATE,
      t0: 0,
      times: Float64Array.from(b.values, (_v, i) => i / RATE),
      values: Float64Array.from(b.values),
    })),
  };
}

/** The engine behind a worker's interface: messages go through structuredClone, as postMessage
 * copies them, and the answer comes back on a later turn (as a worker's would). */
class EngineWorker implements WorkerLike {
  readonly engine = new PlotEngine();
  onmessage: ((e: MessageEvent<PlotReply>) => void) | null = null;
  sent: ToWorker[] = [];
  postMessage(msg: ToWorker): void {
    const copy = structuredClone(msg);
    this.sent.push(copy);
    const reply = this.engine.handle(copy);
    if (reply) queueMicrotask(() => this.onmessage?.({ data: reply } as MessageEvent<PlotReply>));
  }
  terminate(): void {}
}

const settle = () => new Promise<void>((r) => setTimeout(r, 0));

describe('column strokes', () => {
  it('draws a spike between two columns from its column min to max', () => {
    // Three columns at x = 10, 11, 12 px; the middle one holds a spike up to y = 2 px and
    // down to y = 98 px (pixel y grows downwards), its neighbours sit at y = 50.
    const px = [9.75, 10.25, 10.75, 11.25, 11.75, 12.25];
    const py = [50, 50, 2, 98, 50, 50];
    const seg = columnSegments(px, py, 0, 3);
    const middle: number[] = [];
    for (let i = 0; i < seg.length; i += 4) if (seg[i] === 11 && seg[i + 2] === 11) middle.push(seg[i + 1] as number, seg[i + 3] as number);
    expect(Math.min(...middle)).toBe(2);
    expect(Math.max(...middle)).toBe(98);
    // The next column joins the spike's last value (98) down to its own.
    const next = [];
    for (let i = 0; i < seg.length; i += 4) if (seg[i] === 12) next.push(seg[i + 1] as number, seg[i + 3] as number);
    expect(Math.max(...next)).toBe(98);
  });

  it('joins across empty columns and to the samples beyond the window', () => {
    // Left edge sample at x = 0, columns at 10 and 20 px (the ones between empty), right edge at 30.
    const px = [0, 9.75, 10.25, 14.75, 15.25, 19.75, 20.25, 30];
    const py = [40, 60, NaN, NaN, NaN, 70, 80, 90];
    const seg = Array.from(columnSegments(px, py, 1, 3));
    expect(seg.slice(0, 4)).toEqual([0, 40, 10, 60]); // edge to the first column
    expect(seg).toEqual(expect.arrayContaining([10, 60, 20, 70])); // across the empty column
    expect(seg.slice(-4)).toEqual([20, 80, 30, 90]); // last column to the right edge
  });

  it('a flat column still covers one pixel', () => {
    const seg = columnSegments([4.75, 5.25], [30, NaN], 0, 1);
    expect(Array.from(seg)).toEqual([5, 30, 5, 31]);
  });
});

describe('plot engine (the worker)', () => {
  it('keeps the min and max of a one-sample spike on a column boundary', () => {
    // 10 s of 4 kHz, flat, one sample +1000 and the next -1000 exactly where column 37 of
    // 400 starts: both must reach the drawn data.
    const n = 10 * RATE;
    const t = Float64Array.from({ length: n }, (_v, i) => 100 + i / RATE);
    const v = new Float64Array(n);
    const at = Math.round((37 * 10 * RATE) / 400);
    v[at] = 1000;
    v[at + 1] = -1000;
    const engine = new PlotEngine();
    engine.handle({ type: 'recording', channels: [{ id: 3, t, v }] });
    const reply = engine.plot({
      seq: 1,
      store: 'recording',
      traces: [{ kind: 'channel', id: 3, a: 1, b: 0, key: 'c3' }],
      origin: 100,
      x0: 0,
      x1: 10,
      cols: 400,
    });
    expect(reply.decimated).toBe(true);
    expect(reply.points).toBe(n);
    const y = unpackYs(reply.ys)[0] as (number | null)[];
    const values = y.filter((x): x is number => x !== null);
    expect(Math.max(...values)).toBe(1000);
    expect(Math.min(...values)).toBe(-1000);
    // Both in the same column's two slots, in time order.
    const i = y.indexOf(1000);
    expect(y[i + 1]).toBe(-1000);
    expect((i - reply.off) % 2).toBe(0);
  });

  it('answers what the main thread would draw, for live samples appended in pieces', () => {
    const engine = new PlotEngine();
    const t = Float64Array.from({ length: 8000 }, (_v, i) => 5 + i / RATE);
    const v = Float64Array.from({ length: 8000 }, (_v, i) => Math.round(1000 * Math.sin(i / 37)));
    for (let k = 0; k < 8000; k += 80) engine.handle({ type: 'append', id: 1, t: t.slice(k, k + 80), v: v.slice(k, k + 80) });
    const reply = engine.plot({ seq: 1, store: 'live', traces: [{ kind: 'channel', id: 1, a: 2, b: 1, key: 'c1' }, null], origin: 5, x0: 0.3, x1: 1.7, cols: 300 });
    const direct: PlotTrace = { t, v, n: 8000, a: 2, b: 1 };
    const want = buildPlotData([direct, null], 5, 0.3, 1.7, 300);
    expect(Array.from(reply.x)).toEqual(Array.from(want.x));
    expect(unpackYs(reply.ys)).toEqual(want.ys);
    engine.handle({ type: 'clear', ids: [1] });
    expect(engine.live.get(1)?.n).toBe(0);
  });

  it('packs null as NaN and back', () => {
    const ys = [[1, null, -2.5], [null]];
    expect(unpackYs(packYs(ys))).toEqual(ys);
  });
});

describe('plot feed (the page side)', () => {
  it('sends only new samples and draws the window of the newest state', async () => {
    const model = new ScopeModel();
    model.setTraces([trace('c0', 0), trace('c1', 1)]);
    const worker = new EngineWorker();
    let replies = 0;
    const feed = new PlotFeed(model, worker, () => replies++);
    const values = (k: number) => Array.from({ length: 400 }, (_v, i) => ((k * 400 + i) % 97) - 48);
    model.ingest(frame(1, 1000, [{ id: 0, values: values(0) }, { id: 1, values: values(0) }]));
    feed.request(200);
    // A second request while the first is in flight waits for its answer.
    model.ingest(frame(2, 1000.1, [{ id: 0, values: values(1) }, { id: 1, values: values(1) }]));
    feed.request(200);
    await settle();
    expect(replies).toBe(1);
    // Nothing more is computed until the page draws that answer; then the change is asked for.
    await settle();
    expect(replies).toBe(1);
    expect(feed.take()?.points).toBe(800);
    await settle();
    expect(replies).toBe(2);
    const appended = worker.sent.filter((m) => m.type === 'append').map((m) => (m.type === 'append' ? m.t.length : 0));
    // Each sample crossed once: 400 per channel per frame.
    expect(appended).toEqual([400, 400, 400, 400]);
    const r = feed.take() as PlotReply;
    expect(r.points).toBe(1600);
    const want = model.plotData(200);
    expect(Array.from(r.x)).toEqual(Array.from(want.x));
    expect(unpackYs(r.ys)).toEqual(want.ys);
    // A channel cleared and refilled is sent again from its start.
    model.clearLive([1]);
    model.ingest(frame(3, 1000.2, [{ id: 1, values: values(2) }]));
    feed.request(200);
    await settle();
    expect(worker.engine.live.get(1)?.n).toBe(400);
    expect(worker.engine.live.get(0)?.n).toBe(800);
    feed.dispose();
  });
});

describe('smooth following of live samples (the play-head)', () => {
  it('moves every frame with the wall clock, behind the newest sample, never backwards', () => {
    const model = new ScopeModel();
    let wall = 50;
    model.now = () => wall;
    model.smooth = true;
    model.running = true;
    model.span = 1;
    model.setTraces([trace('c0', 0)]);
    // Frames of 0.14 s of samples arrive every 0.14 s, each 0.05 s after its last sample.
    const per = Math.round(0.14 * RATE);
    let k = 0;
    const arrive = () => {
      model.ingest(frame(k + 1, 1000 + (k * per) / RATE, [{ id: 0, values: new Array<number>(per).fill(k) }]));
      k++;
    };
    const edges: number[] = [];
    const newest: number[] = [];
    for (let f = 0; f < 60 * 3; f++) {
      // 60 animation frames a second; a frame of samples every 0.14 s.
      while (k * 0.14 <= f / 60 + 1e-9) {
        wall = 50 + k * 0.14 + 0.05;
        arrive();
      }
      wall = 50 + f / 60 + 0.05;
      model.tick();
      edges.push(model.window()[1]);
      newest.push(model.latest() as number);
    }
    // After the first second the edge advances on (nearly) every frame, by about 1/60 s ...
    const steps = edges.slice(60).map((e, i) => e - (edges[59 + i] as number));
    expect(steps.every((d) => d >= 0)).toBe(true);
    expect(steps.filter((d) => d > 0).length).toBeGreaterThan(0.9 * steps.length);
    const median = [...steps].sort((a, b) => a - b)[Math.floor(steps.length / 2)] as number;
    expect(median).toBeCloseTo(1 / 60, 2);
    // ... and never shows past the newest sample (once the run is longer than the window).
    edges.forEach((e, i) => {
      if (i >= 60) expect(e).toBeLessThanOrEqual((newest[i] as number) + 1e-9);
    });
  });

  it('is off on the former path: the view moves only when samples arrive', () => {
    const model = new ScopeModel();
    model.running = true;
    model.setTraces([trace('c0', 0)]);
    model.ingest(frame(1, 1000, [{ id: 0, values: [1, 2, 3, 4] }]));
    const before = model.window();
    expect(model.tick(1e9)).toBe(false);
    expect(model.window()).toEqual(before);
  });
});
