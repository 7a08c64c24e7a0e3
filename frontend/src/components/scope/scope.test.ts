import { describe, expect, it } from 'vitest';
import { DecimationCache, buildPlotData, type PlotTrace } from './decimate';
import { mathChannel, mathUnit } from './math';
import { ScopeModel, type TraceDef } from './model';
import { normaliseRecording } from './recording';
import { MAX_SAMPLES, Series, TOTAL_SAMPLES, lowerBound, nearestIndex, share, upperBound } from './series';
import { cursorDelta, rangeStats, transformStats, windowStats } from './stats';
import { FLAG_SKIPPED, KIND_CAPTURE, KIND_SAMPLES, KIND_STATUS, decodeFrame } from '../../scope/wire';

/**
 * A frame in the layout of docs/scope.md "Wire format" (the server is the real encoder; this
 * one only feeds the decoder and the model here).
 */
function encodeFrame(
  kind: number,
  seq: number,
  skipped: number,
  tRef: number,
  blocks: readonly { id: number; source: number; dt: number; t0: number; times?: readonly number[]; values: readonly number[] }[],
  flags = 0,
): ArrayBuffer {
  let size = 32;
  for (const b of blocks) size += 24 + (b.dt === 0 ? 16 : 8) * b.values.length;
  const buf = new ArrayBuffer(size);
  const dv = new DataView(buf);
  'SDSC'.split('').forEach((c, i) => dv.setUint8(i, c.charCodeAt(0)));
  dv.setUint8(4, 1);
  dv.setUint8(5, kind);
  dv.setUint16(6, flags, true);
  dv.setUint32(8, seq, true);
  dv.setUint32(12, skipped, true);
  dv.setUint16(16, blocks.length, true);
  dv.setFloat64(24, tRef, true);
  let off = 32;
  for (const b of blocks) {
    const n = b.values.length;
    dv.setUint8(off, b.id);
    dv.setUint8(off + 1, b.source);
    dv.setUint32(off + 4, n, true);
    dv.setFloat64(off + 8, b.dt, true);
    dv.setFloat64(off + 16, b.t0, true);
    off += 24;
    if (b.dt === 0) for (let i = 0; i < n; i++, off += 8) dv.setFloat64(off, b.times?.[i] ?? 0, true);
    for (let i = 0; i < n; i++, off += 8) dv.setFloat64(off, b.values[i] ?? 0, true);
  }
  return buf;
}

function trace(t: number[], v: number[], a = 1, b = 0): PlotTrace {
  return { t: Float64Array.from(t), v: Float64Array.from(v), n: t.length, a, b };
}

function range(n: number, f: (i: number) => number): number[] {
  return Array.from({ length: n }, (_, i) => f(i));
}

function channel(id: number, over: Partial<TraceDef> = {}): TraceDef {
  return {
    key: `c${id}`,
    kind: 'channel',
    id,
    label: `ch${id}`,
    colour: '#000',
    visible: true,
    unit: 'deg',
    rawUnit: 'inc',
    engScale: 1,
    scale: 1,
    offset: 0,
    ...over,
  };
}

describe('Series', () => {
  it('appends equidistant and timed samples in place and keeps times increasing', () => {
    const s = new Series(4);
    s.append(100, 0, 0.001, null, [1, 2, 3]);
    s.append(100, 0.003, 0, [0.003, 0.004, 0.0035], [4, 5, 6]);
    expect(s.n).toBe(5);
    expect(Array.from(s.v.subarray(0, s.n))).toEqual([1, 2, 3, 4, 5]);
    expect(s.t[3]).toBeCloseTo(100.003, 9);
    expect(s.t.length).toBeGreaterThanOrEqual(5);
  });

  it('stays within its bound by dropping the oldest samples', () => {
    const s = new Series(8, 100);
    for (let k = 0; k < 10; k++) s.append(k * 0.05, 0, 0.001, null, range(50, (i) => k * 50 + i));
    expect(s.n).toBeLessThanOrEqual(100);
    expect(s.v[s.n - 1]).toBe(499);
    // Still contiguous: the newest n values are n consecutive samples.
    expect(s.v[0]).toBe(500 - s.n);
    expect(s.dropped).toBe(500 - s.n);
  });

  it('shares one memory budget among the live channels: 8 keep 131 s at 4 kHz, 32 keep 33 s', () => {
    const live = new Map<number, Series>();
    for (let id = 0; id < 8; id++) live.set(id, new Series());
    share(live);
    expect([...live.values()].every((s) => s.max === MAX_SAMPLES)).toBe(true);
    for (let id = 8; id < 32; id++) live.set(id, new Series());
    share(live);
    const max = live.get(0)?.max ?? 0;
    expect(max * 32).toBe(TOTAL_SAMPLES);
    expect(max / 4000).toBeGreaterThan(30); // still far more than the 10 s window
    // A series over its new share drops its oldest samples on the next append.
    const s = new Series(8, 100);
    s.append(0, 0, 1, null, new Float64Array(100));
    s.max = 40;
    s.append(0, 100, 1, null, new Float64Array(1));
    expect(s.n).toBeLessThanOrEqual(40);
    expect(s.t[s.n - 1]).toBe(100);
  });

  it('finds bounds and the nearest sample', () => {
    const t = Float64Array.from([0, 1, 2, 3]);
    expect(lowerBound(t, 4, 1)).toBe(1);
    expect(upperBound(t, 4, 1)).toBe(2);
    expect(lowerBound(t, 4, 5)).toBe(4);
    expect(nearestIndex(t, 4, 1.4)).toBe(1);
    expect(nearestIndex(t, 4, 1.6)).toBe(2);
    expect(nearestIndex(t, 0, 1)).toBe(-1);
  });
});

describe('buildPlotData', () => {
  it('draws the samples as they are when there are fewer than pixel columns', () => {
    const a = trace([0, 1, 2, 3, 4], [0, 10, 20, 30, 40]);
    const b = trace([0.5, 2.5], [5, 6], 2, 1);
    const d = buildPlotData([a, b], 0, 1, 3, 100);
    expect(d.decimated).toBe(false);
    // One sample either side of the window is kept so lines reach the edges.
    expect(Array.from(d.x)).toEqual([0, 0.5, 1, 2, 2.5, 3, 4]);
    expect(d.ys[0]).toEqual([0, null, 10, 20, null, 30, 40]);
    expect(d.ys[1]).toEqual([null, 11, null, null, 13, null, null]);
    expect(d.points).toBe(3 + 1);
  });

  it('keeps each column minimum and maximum when decimating, in their order', () => {
    const n = 100_000;
    const t = range(n, (i) => i / n);
    const v = range(n, (i) => Math.sin(2 * Math.PI * 5 * (i / n)));
    // One spike a single sample wide, in each direction.
    v[12_345] = 7;
    v[67_890] = -9;
    const tr = trace(t, v);
    const d = buildPlotData([tr], 0, 0, 1, 500);
    expect(d.decimated).toBe(true);
    expect(d.x.length).toBeLessThanOrEqual(2 * 500 + 2);
    const ys = d.ys[0] as (number | null)[];
    const shown = ys.filter((y): y is number => y !== null);
    expect(Math.max(...shown)).toBe(7);
    expect(Math.min(...shown)).toBe(-9);
    // Every column's min and max equal the stored samples' own min and max of that column.
    const w = 1 / 500;
    for (let c = 0; c < 500; c += 37) {
      const col = v.filter((_, i) => (t[i] as number) >= c * w && (c === 499 || (t[i] as number) < (c + 1) * w));
      const pair = [ys[2 * c], ys[2 * c + 1]].filter((y): y is number => y !== null);
      expect(Math.min(...pair)).toBe(Math.min(...col));
      expect(Math.max(...pair)).toBe(Math.max(...col));
    }
    // The stored data is untouched.
    expect(tr.v[12_345]).toBe(7);
    expect(tr.n).toBe(n);
  });

  it('applies the shown transform and leaves hidden traces empty', () => {
    const tr = trace(range(2000, (i) => i * 0.001), range(2000, () => 3), 2, 1);
    const d = buildPlotData([tr, null], 0, 0, 2, 100);
    expect(d.decimated).toBe(true);
    expect(new Set(d.ys[0]?.filter((y) => y !== null))).toEqual(new Set([7]));
    expect(d.ys[1]?.every((y) => y === null)).toBe(true);
  });
});

describe('column cache', () => {
  it('gives while panning exactly what a fresh decimation gives', () => {
    const n = 40_000;
    const tr = trace(range(n, (i) => 1000 + i / 4000), range(n, (i) => Math.round(1000 * Math.sin(i / 300)) + (i % 97 === 0 ? 5000 : 0)));
    const keyed: PlotTrace = { ...tr, key: 'c0', generation: '0' };
    const cache = new DecimationCache();
    for (let k = 0; k < 40; k++) {
      // Pan by amounts whose float rounding differs, zoomed to 4 s of the 10 s.
      const x0 = 1 + k * 0.0137;
      const x1 = x0 + 4;
      const cached = buildPlotData([keyed], 1000, x0, x1, 700, cache);
      const fresh = buildPlotData([tr], 1000, x0, x1, 700);
      expect(cached.decimated).toBe(true);
      expect(Array.from(cached.x)).toEqual(Array.from(fresh.x));
      expect(cached.ys).toEqual(fresh.ys);
    }
  });

  it('recomputes the newest column when samples are appended to a live series', () => {
    // Room for every sample: the arrays stay the same, so the cache is used.
    const s = new Series(8192);
    s.append(0, 0, 0.001, null, range(3000, (i) => i % 50));
    const cache = new DecimationCache();
    const view = () => ({ t: s.t, v: s.v, n: s.n, a: 1, b: 0, key: 'c0', generation: `${s.epoch}:${s.dropped}` });
    buildPlotData([view()], 0, 0, 4, 500, cache);
    // A spike lands in the column that was the last, partial one.
    s.append(0, 3, 0.001, null, [999, ...range(999, () => 1)]);
    const cached = buildPlotData([view()], 0, 0, 4, 500, cache);
    const fresh = buildPlotData([{ ...view(), key: undefined }], 0, 0, 4, 500);
    expect(cached.ys).toEqual(fresh.ys);
    expect(Math.max(...(cached.ys[0] as number[]).filter((y) => y !== null))).toBe(999);
    // Cleared and refilled: nothing of the old samples stays.
    s.clear();
    s.append(0, 0, 0.001, null, range(4000, () => -7));
    const after = buildPlotData([view()], 0, 0, 4, 500, cache);
    expect(new Set((after.ys[0] as (number | null)[]).filter((y) => y !== null))).toEqual(new Set([-7]));
  });
});

describe('stats', () => {
  it('gives min, max, mean, RMS, frequency and rate of a sine', () => {
    const rate = 4000;
    const t = Float64Array.from(range(4000, (i) => i / rate));
    const v = Float64Array.from(range(4000, (i) => 2 + 3 * Math.sin(2 * Math.PI * 50 * (i / rate) + 0.1)));
    const s = rangeStats(t, v, 0, 4000);
    expect(s.n).toBe(4000);
    expect(s.min).toBeCloseTo(-1, 2);
    expect(s.max).toBeCloseTo(5, 2);
    expect(s.mean).toBeCloseTo(2, 3);
    expect(s.rms).toBeCloseTo(Math.sqrt(4 + 4.5), 3);
    expect(s.freqHz).toBeCloseTo(50, 1);
    expect(s.rateHz).toBeCloseTo(4000, 6);
  });

  it('transforms like the values: shown = a * raw + b', () => {
    const t = Float64Array.from([0, 1, 2, 3]);
    const raw = [1, -2, 4, 3];
    const s = rangeStats(t, Float64Array.from(raw), 0, 4);
    const a = -0.5;
    const b = 10;
    const direct = rangeStats(t, Float64Array.from(raw.map((x) => a * x + b)), 0, 4);
    const via = transformStats(s, a, b);
    expect(via.min).toBeCloseTo(direct.min as number, 12);
    expect(via.max).toBeCloseTo(direct.max as number, 12);
    expect(via.mean).toBeCloseTo(direct.mean as number, 12);
    expect(via.rms).toBeCloseTo(direct.rms as number, 12);
  });

  it('counts only the samples in the window', () => {
    const t = Float64Array.from([0, 1, 2, 3, 4]);
    const v = Float64Array.from([100, 1, 2, 3, 100]);
    const s = windowStats(t, v, 5, 1, 3);
    expect(s.n).toBe(3);
    expect(s.max).toBe(3);
  });

  it('gives delta-t and 1/delta-t of the cursors', () => {
    const d = cursorDelta(0.1, 0.35);
    expect(d.dt).toBeCloseTo(0.25, 12);
    expect(d.inv).toBeCloseTo(4, 12);
    expect(cursorDelta(0.35, 0.1).inv).toBeCloseTo(4, 12);
    expect(cursorDelta(null, 1)).toEqual({ dt: null, inv: null });
    expect(cursorDelta(1, 1).inv).toBeNull();
  });
});

describe('math channels', () => {
  const a = { t: Float64Array.from([0, 1, 2, 3]), v: Float64Array.from([0, 2, 4, 6]), n: 4 };
  const b = { t: Float64Array.from([0.5, 2.5]), v: Float64Array.from([1, 3]), n: 2 };

  it('differences and sums at the first channel times, the second interpolated, never extrapolated', () => {
    const d = mathChannel('diff', a, b);
    expect(Array.from(d.t)).toEqual([1, 2]);
    expect(Array.from(d.v)).toEqual([2 - 1.5, 4 - 2.5]);
    const s = mathChannel('sum', a, b);
    expect(Array.from(s.v)).toEqual([3.5, 6.5]);
  });

  it('derives by the backward difference', () => {
    const d = mathChannel('deriv', { t: Float64Array.from([0, 0.5, 1.5]), v: Float64Array.from([0, 1, 4]), n: 3 }, null);
    expect(Array.from(d.t)).toEqual([0.5, 1.5]);
    expect(Array.from(d.v)).toEqual([2, 3]);
  });

  it('names the unit of the result', () => {
    expect(mathUnit('deriv', 'deg', null)).toBe('deg/s');
    expect(mathUnit('diff', 'deg', 'deg')).toBe('deg');
  });

  it('computes a math channel in the model on the shown values', () => {
    const m = new ScopeModel();
    m.openRecording(
      {
        triggerTime: null,
        channels: [
          { id: 0, t: [10, 11, 12], v: [0, 10, 20] },
          { id: 1, t: [10, 11, 12], v: [1, 1, 1] },
        ],
      },
      'recording',
    );
    m.setTraces([
      channel(0, { engScale: 0.5 }),
      channel(1, { offset: 2 }),
      { ...channel(0), key: 'm0', kind: 'math', id: 0, op: 'diff', a: 0, b: 1 },
      { ...channel(0), key: 'm1', kind: 'math', id: 1, op: 'deriv', a: 0, b: null },
    ]);
    const stats = m.stats();
    const diff = stats.find((s) => s.key === 'm0');
    // shown a = 0.5 * raw = 0, 5, 10; shown b = raw + 2 = 3: a - b = -3, 2, 7.
    expect(diff?.shown.min).toBe(-3);
    expect(diff?.shown.max).toBe(7);
    expect(diff?.shown.mean).toBe(2);
    // raw: 0-1, 10-1, 20-1.
    expect(diff?.raw.max).toBe(19);
    const deriv = stats.find((s) => s.key === 'm1');
    expect(deriv?.shown.mean).toBe(5);
    const at = m.valuesAt(1);
    expect(at.find((c) => c.key === 'c0')).toMatchObject({ t: 1, raw: 10, shown: 5 });
  });
});

describe('wire frames into the model', () => {
  it('decodes equidistant and timed blocks and a status frame', () => {
    const buf = encodeFrame(
      KIND_SAMPLES,
      7,
      2,
      1_700_000_000.25,
      [
        { id: 0, source: 3, dt: 0.00025, t0: 0.001, values: [1, 2, 3] },
        { id: 5, source: 2, dt: 0, t0: 0.002, times: [0.002, 0.0125], values: [-4, 5.5] },
      ],
      FLAG_SKIPPED,
    );
    const f = decodeFrame(buf);
    expect(f).toMatchObject({ version: 1, kind: KIND_SAMPLES, seq: 7, skipped: 2, flags: FLAG_SKIPPED, tRef: 1_700_000_000.25 });
    expect(f.blocks).toHaveLength(2);
    expect(f.blocks[0]).toMatchObject({ id: 0, source: 3, n: 3, dt: 0.00025, t0: 0.001 });
    expect(Array.from(f.blocks[0]?.values ?? [])).toEqual([1, 2, 3]);
    expect(Array.from(f.blocks[1]?.times ?? [])).toEqual([0.002, 0.0125]);
    expect(Array.from(f.blocks[1]?.values ?? [])).toEqual([-4, 5.5]);

    const status = new TextEncoder().encode(JSON.stringify({ type: 'status', state: 'armed', channels: [] }));
    const head = new Uint8Array(encodeFrame(KIND_STATUS, 8, 2, 0, []));
    const whole = new Uint8Array(head.length + status.length);
    whole.set(head);
    whole.set(status, head.length);
    expect(decodeFrame(whole.buffer).status).toEqual({ type: 'status', state: 'armed', channels: [] });
  });

  it('refuses a frame that is not one', () => {
    expect(() => decodeFrame(new ArrayBuffer(8))).toThrow(/truncated/);
    const bad = new Uint8Array(encodeFrame(KIND_SAMPLES, 0, 0, 0, []));
    bad[0] = 0x58;
    expect(() => decodeFrame(bad.buffer)).toThrow(/not a scope frame/);
  });

  it('appends sample frames in place, follows the newest, counts skips and opens captures', () => {
    const m = new ScopeModel();
    m.setTraces([channel(0)]);
    const tRef = 1_700_000_000;
    for (let k = 0; k < 50; k++) {
      const values = range(120, (i) => k * 120 + i);
      m.ingest(decodeFrame(encodeFrame(KIND_SAMPLES, k, 0, tRef, [{ id: 0, source: 3, dt: 0.00025, t0: k * 0.03, values }])));
    }
    const s = m.seriesOf(0);
    expect(s?.n).toBe(6000);
    expect(s?.v[5999]).toBe(5999);
    expect(m.skipped).toBe(0);
    // 1.5 s of data with a 1 s window: the view follows the newest sample.
    m.setSpan(1);
    const [x0, x1] = m.window();
    // Backend times near 1.7e9 s hold about 0.2 µs.
    expect(x1).toBeCloseTo(5999 * 0.00025, 6);
    expect(x1 - x0).toBeCloseTo(1, 9);
    // 1 s of 4 kHz samples (the edge sample in or out, by rounding).
    expect(m.stats()[0]?.raw.n).toBeGreaterThanOrEqual(4000);
    expect(m.stats()[0]?.raw.n).toBeLessThanOrEqual(4001);

    m.ingest(decodeFrame(encodeFrame(KIND_SAMPLES, 50, 3, tRef, [], FLAG_SKIPPED)));
    expect(m.skipped).toBe(3);
    expect(m.skippedRecently).toBe(true);

    m.ingest(decodeFrame(encodeFrame(KIND_CAPTURE, 51, 3, tRef + 10, [{ id: 0, source: 3, dt: 0.001, t0: -0.2, values: range(1000, (i) => i) }])));
    expect(m.kind).toBe('capture');
    expect(m.seriesOf(0)?.n).toBe(1000);
    // The live samples are still there for when the view goes back to live.
    expect(m.live.get(0)?.n).toBe(6000);
  });

  it('counts skips from the server and from gaps, not the status frames between samples', () => {
    const m = new ScopeModel();
    const samples = (seq: number, skipped = 0) =>
      decodeFrame(encodeFrame(KIND_SAMPLES, seq, skipped, 1000, [{ id: 0, source: 1, dt: 0.001, t0: seq, values: [seq] }], skipped ? FLAG_SKIPPED : 0));
    const status = new TextEncoder().encode(JSON.stringify({ type: 'status', state: 'rolling', channels: [] }));
    const statusFrame = (seq: number) => {
      const head = new Uint8Array(encodeFrame(KIND_STATUS, seq, 0, 0, []));
      const whole = new Uint8Array(head.length + status.length);
      whole.set(head);
      whole.set(status, head.length);
      return decodeFrame(whole.buffer);
    };
    m.ingest(samples(1));
    m.noteFrame(statusFrame(2));
    m.ingest(samples(3));
    expect(m.skipped).toBe(0);
    expect(m.frames).toBe(2);
    // The server dropped two frames for this client: it says so in the next header.
    m.ingest(samples(4, 2));
    expect(m.skipped).toBe(2);
    expect(m.skippedRecently).toBe(true);
    // A gap in the numbers (never expected) is counted too.
    m.ingest(samples(7, 2));
    expect(m.skipped).toBe(4);
  });

  it('opens a recording with the trigger at x = 0 and zooms and pans', () => {
    const m = new ScopeModel();
    m.setTraces([channel(0)]);
    m.openRecording({ triggerTime: 100.2, channels: [{ id: 0, t: range(1001, (i) => 100 + i * 0.001), v: range(1001, (i) => i) }] }, 'capture');
    const [x0, x1] = m.window();
    expect(x0).toBeCloseTo(-0.2, 9);
    expect(x1).toBeCloseTo(0.8, 9);
    m.zoomTo(0, 0.1);
    m.pan(0.05);
    expect(m.window()[0]).toBeCloseTo(0.05, 9);
    m.zoomAround(0.1, 2);
    expect(m.window()[1] - m.window()[0]).toBeCloseTo(0.2, 9);
    m.resetZoom();
    expect(m.window()[0]).toBeCloseTo(-0.2, 9);
  });
});

describe('reset zoom', () => {
  it('shows the whole run after Stop, not the last window', () => {
    const m = new ScopeModel();
    m.setTraces([channel(0)]);
    // 5 s of samples at 1 kHz.
    m.ingest(decodeFrame(encodeFrame(KIND_SAMPLES, 1, 0, 1000, [{ id: 0, source: 3, dt: 0.001, t0: 0, values: range(5000, (i) => i) }])));
    m.span = 1;
    m.setRunning(true);
    m.resetZoom();
    const [r0, r1] = m.window();
    expect(r1 - r0).toBeCloseTo(1, 9);
    m.setRunning(false);
    m.resetZoom();
    const e = m.extent();
    expect(e).not.toBeNull();
    expect(m.window()).toEqual(e);
    expect((e as [number, number])[1] - (e as [number, number])[0]).toBeGreaterThan(1);
  });
});

describe('recordings from the server', () => {
  it('opens a capture: times from t_ref, the profile and display scales, the trigger', () => {
    const n = normaliseRecording({
      t_ref: 1_700_000_000.5,
      trigger_time: 1_700_000_000.5,
      channels: [
        {
          id: 3,
          t: [-0.2, -0.1, 0, 0.1],
          v: [1, 2, null, 4],
          name: 'Position actual value',
          label: null,
          unit: 'deg',
          raw_unit: 'inc',
          scale: 0.0027,
          eng_scale: 0.0027,
          display_scale: 2,
          offset: 5,
          address: '0x6064:00',
          session: 's1',
          source: 'recorder',
        },
      ],
    });
    expect(n.samples).toBe(3);
    expect(n.open.triggerTime).toBe(1_700_000_000.5);
    const c = n.open.channels[0];
    expect(Array.from(c?.t ?? [])).toEqual([1_700_000_000.3, 1_700_000_000.4, 1_700_000_000.6]);
    expect(Array.from(c?.v ?? [])).toEqual([1, 2, 4]);
    expect(n.meta[0]).toMatchObject({ id: 3, label: 'Position actual value', unit: 'deg', rawUnit: 'inc', engScale: 0.0027, scale: 2, offset: 5, samples: 3 });
  });

  it('opens an imported file: the profile scale, no display scale, times already absolute kept', () => {
    // A file's column without a title: an imported channel has no address or session
    // (domain/scope_export.py), and here no name either.
    const imported = { name: '', unit: '', raw_unit: '', address: '', session: '', source: 'import' };
    const n = normaliseRecording({
      t_ref: 0,
      trigger_time: null,
      channels: [{ id: 0, t: [1_700_000_000, 1_700_000_001], v: [7, 8], scale: 0.5, ...imported }],
    });
    expect(Array.from(n.open.channels[0]?.t ?? [])).toEqual([1_700_000_000, 1_700_000_001]);
    expect(n.meta[0]).toMatchObject({ engScale: 0.5, scale: 1, offset: 0, label: 'channel 0' });
    expect(n.open.triggerTime).toBeNull();
  });
});
