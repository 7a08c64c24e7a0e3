/**
 * The scope's plot on uPlot: draws the model's visible window at most once per animation
 * frame (uPlot `setData` with the window's, display-decimated, data), with zoom by dragging a
 * range, pan by shift-drag or the wheel (ctrl+wheel zooms around the pointer), a click to
 * place the active cursor, the two cursors and the trigger drawn on the canvas, and a PNG of
 * the view with its legend.
 *
 * uPlot is rebuilt only when the traces change (names, colours, units); new data and a moved
 * window only call setData and setScale in one batch.
 *
 * While capturing, the view follows a play-head that moves every animation frame (model.tick):
 * it used to follow the newest sample, so it moved, and the plot redrew, only when a frame of
 * samples arrived (7-8 times a second with the drive's recorder, whose data comes in uploads).
 * The min/max per pixel column is computed in a worker (plotFeed.ts, plot.worker.ts) and a
 * decimated trace is drawn as one vertical stroke per column (columns.ts), so the page's main
 * thread only draws (docs/scope.md "Drawing"). `?plot=main` in the page's URL selects the
 * former path (no play-head, decimation on the main thread, uPlot's polyline) for comparison
 * (bench/bench_scope_ui.py).
 */
import { useEffect, useRef } from 'react';
import { plotColors, themeState } from '../../lib/theme';
import uPlot from 'uplot';
import { columnSegments } from './columns';
import type { ScopeModel, TraceDef } from './model';
import { PlotFeed, startPlotWorker } from './plotFeed';
import { unpackYs } from './plotEngine';

/** What the page wants drawn besides the traces. */
export interface Overlay {
  /** Trigger level line: the trace key it belongs to and the shown value. */
  level: { key: string; value: number } | null;
}

export interface PlotApi {
  /** The view as a PNG with a legend below it (lines of text with colour swatches). */
  png: (title: string, legend: readonly { colour: string; text: string }[]) => Promise<Blob | null>;
}

interface Props {
  model: ScopeModel;
  overlay: React.MutableRefObject<Overlay>;
  onPlaceCursor: (x: number) => void;
  onApi?: (api: PlotApi | null) => void;
  height?: number;
}

const FONT = '11px ui-monospace, "DejaVu Sans Mono", monospace';
// Canvas colours come from the theme's tokens when the plot is built (lib/theme.ts); a theme
// change builds it again (the theme is part of the signature the draw checks).
const grid = () => ({ stroke: plotColors().grid, width: 1 });

function scaleKey(unit: string): string {
  return `y:${unit}`;
}

function signature(traces: readonly TraceDef[]): string {
  return traces.map((t) => `${t.key}|${t.label}|${t.colour}|${t.unit}`).join(';');
}

/** Tick labels with as many decimals as the tick spacing needs. */
function ticks(values: number[], suffix = ''): string[] {
  const step = values.length > 1 ? Math.abs((values[1] as number) - (values[0] as number)) : 1;
  const dec = step > 0 ? Math.max(0, Math.min(9, -Math.floor(Math.log10(step)) + (step / 10 ** Math.floor(Math.log10(step)) < 1.5 ? 1 : 0))) : 0;
  return values.map((v) => {
    const a = Math.abs(v);
    if (a !== 0 && (a >= 1e7 || a < 1e-4)) return v.toExponential(2) + suffix;
    return v.toFixed(dec) + suffix;
  });
}

/** Which path draws: the worker and column strokes, or (`?plot=main`) all on the main thread. */
export function plotPath(): 'worker' | 'main' {
  if (typeof Worker === 'undefined') return 'main';
  return new URLSearchParams(window.location.search).get('plot') === 'main' ? 'main' : 'worker';
}

/** Where the columns are in the data being drawn (null: not decimated, drawn as lines). */
interface Layout {
  columns: { off: number; count: number } | null;
}

const linear = uPlot.paths.linear?.();

/** uPlot path builder: decimated data as column strokes (columns.ts), else uPlot's lines. */
function columnPaths(layout: Layout): uPlot.Series.PathBuilder {
  // The slots' x pixels are the same for every trace of a draw: computed once per data and scale.
  let xsOf: unknown = null;
  let xMin = NaN;
  let xMax = NaN;
  let px = new Float64Array(0);
  let py = new Float64Array(0);
  return (u, sidx, i0, i1) => {
    const cols = layout.columns;
    if (!cols) return linear ? linear(u, sidx, i0, i1) : null;
    const xs = u.data[0];
    const ys = u.data[sidx] as (number | null | undefined)[];
    const { left, top, width, height } = u.bbox;
    const sx = u.scales.x;
    const sy = u.scales[u.series[sidx]?.scale ?? 'y'];
    if (!sx || !sy || sx.min == null || sx.max == null || sy.min == null || sy.max == null) return null;
    if (xsOf !== xs || xMin !== sx.min || xMax !== sx.max) {
      // Linear scales (buildOptions): value to canvas pixel is one multiply-add.
      const kx = width / (sx.max - sx.min || 1);
      px = new Float64Array(xs.length);
      for (let i = 0; i < xs.length; i++) px[i] = left + ((xs[i] as number) - sx.min) * kx;
      py = new Float64Array(xs.length);
      xsOf = xs;
      xMin = sx.min;
      xMax = sx.max;
    }
    const ky = height / (sy.max - sy.min || 1);
    for (let i = 0; i < xs.length; i++) {
      const y = ys[i];
      py[i] = y === null || y === undefined ? NaN : top + (sy.max - y) * ky;
    }
    const seg = columnSegments(px, py, cols.off, cols.count);
    const path = new Path2D();
    for (let k = 0; k + 3 < seg.length; k += 4) {
      path.moveTo(seg[k] as number, seg[k + 1] as number);
      path.lineTo(seg[k + 2] as number, seg[k + 3] as number);
    }
    return { stroke: path, fill: null, clip: null, band: null, flags: 0 };
  };
}

function buildOptions(
  model: ScopeModel,
  width: number,
  height: number,
  overlay: React.MutableRefObject<Overlay>,
  onZoom: (x0: number, x1: number) => void,
  layout: Layout | null,
): uPlot.Options {
  const units: string[] = [];
  for (const t of model.traces) if (!units.includes(t.unit)) units.push(t.unit);
  if (!units.length) units.push('');
  const scales: uPlot.Scales = { x: { time: false, auto: false } };
  for (const u of units) scales[scaleKey(u)] = { auto: true };
  const axes: uPlot.Axis[] = [
    {
      stroke: plotColors().axis,
      grid: grid(),
      ticks: { stroke: plotColors().ticks, width: 1 },
      font: FONT,
      values: (_u, v) => ticks(v, ' s'),
    },
  ];
  units.forEach((u, i) => {
    const first = model.traces.find((t) => t.unit === u);
    axes.push({
      scale: scaleKey(u),
      show: i < 2,
      side: i === 0 ? 3 : 1,
      stroke: first?.colour ?? plotColors().axis,
      grid: i === 0 ? grid() : { show: false },
      font: FONT,
      size: 70,
      label: u || undefined,
      labelFont: FONT,
      labelSize: 14,
      values: (_u, v) => ticks(v),
    });
  });
  const series: uPlot.Series[] = [{ label: 't' }];
  for (const t of model.traces) {
    series.push({
      label: t.label,
      scale: scaleKey(t.unit),
      stroke: t.colour,
      width: 1,
      dash: t.kind === 'math' ? [6, 3] : undefined,
      spanGaps: true,
      ...(layout ? { paths: columnPaths(layout) } : {}),
    });
  }
  return {
    width,
    height,
    legend: { show: false },
    cursor: {
      drag: { x: true, y: false, setScale: false, dist: 5 },
      points: { show: false },
    },
    scales,
    axes,
    series,
    hooks: {
      setSelect: [
        (u) => {
          if (u.select.width > 4) {
            const x0 = u.posToVal(u.select.left, 'x');
            const x1 = u.posToVal(u.select.left + u.select.width, 'x');
            onZoom(x0, x1);
          }
          u.setSelect({ left: 0, top: 0, width: 0, height: 0 }, false);
        },
      ],
      draw: [
        (u) => {
          model.draws++;
          const { ctx } = u;
          const { left, top, width: w, height: h } = u.bbox;
          const px = uPlot.pxRatio;
          ctx.save();
          ctx.beginPath();
          ctx.rect(left, top, w, h);
          ctx.clip();
          const vline = (x: number, colour: string, dash: number[], label: string) => {
            const cx = Math.round(u.valToPos(x, 'x', true));
            if (cx < left || cx > left + w) return;
            ctx.strokeStyle = colour;
            ctx.lineWidth = px;
            ctx.setLineDash(dash.map((d) => d * px));
            ctx.beginPath();
            ctx.moveTo(cx + 0.5, top);
            ctx.lineTo(cx + 0.5, top + h);
            ctx.stroke();
            ctx.setLineDash([]);
            ctx.fillStyle = colour;
            ctx.font = `${11 * px}px ui-monospace, monospace`;
            ctx.fillText(label, cx + 3 * px, top + 12 * px);
          };
          if (model.kind !== 'live' && model.triggerTime !== null) vline(0, '#c0262d', [2, 3], 'T');
          const cursor = plotColors().text;
          if (model.cursorA !== null) vline(model.cursorA, cursor, [], 'A');
          if (model.cursorB !== null) vline(model.cursorB, cursor, [5, 3], 'B');
          const lv = overlay.current.level;
          const tr = lv ? model.traces.find((t) => t.key === lv.key) : null;
          if (lv && tr) {
            const cy = Math.round(u.valToPos(lv.value, scaleKey(tr.unit), true));
            if (cy >= top && cy <= top + h) {
              ctx.strokeStyle = tr.colour;
              ctx.lineWidth = px;
              ctx.setLineDash([2 * px, 4 * px]);
              ctx.beginPath();
              ctx.moveTo(left, cy + 0.5);
              ctx.lineTo(left + w, cy + 0.5);
              ctx.stroke();
              ctx.setLineDash([]);
              ctx.fillStyle = tr.colour;
              ctx.font = `${11 * px}px ui-monospace, monospace`;
              ctx.fillText('trigger level', left + 4 * px, cy - 3 * px);
            }
          }
          ctx.restore();
        },
      ],
    },
  };
}

export function ScopePlot({ model, overlay, onPlaceCursor, onApi, height = 380 }: Props) {
  const host = useRef<HTMLDivElement | null>(null);
  const placeRef = useRef(onPlaceCursor);
  placeRef.current = onPlaceCursor;
  const apiRef = useRef(onApi);
  apiRef.current = onApi;

  useEffect(() => {
    const found = host.current;
    if (!found) return;
    const el: HTMLDivElement = found;
    let plot: uPlot | null = null;
    let built = '';
    let frame = 0;
    const widthOf = () => Math.max(300, el.clientWidth);
    const path = plotPath();
    el.dataset.path = path;
    const layout: Layout | null = path === 'worker' ? { columns: null } : null;

    const shape = () => `${signature(model.traces)}|${themeState.get().theme}`;
    const build = () => {
      plot?.destroy();
      built = shape();
      plot = new uPlot(buildOptions(model, widthOf(), height, overlay, (x0, x1) => model.zoomTo(x0, x1), layout), [[]], el);
      attach(plot);
    };
    const columnsOf = (u: uPlot) => Math.max(50, Math.round(u.over.clientWidth || u.bbox.width / uPlot.pxRatio));

    const show = (u: uPlot, x: Float64Array, ys: (number | null)[][], window: [number, number], points: number, decimated: boolean) => {
      const [x0, x1] = window;
      u.batch(() => {
        u.setData([x, ...ys] as uPlot.AlignedData, false);
        u.setScale('x', { min: x0, max: x1 > x0 ? x1 : x0 + 1e-3 });
      });
      el.dataset.length = String(x.length);
      el.dataset.points = String(points);
      el.dataset.samples = String(model.sampleCount());
      el.dataset.decimated = String(decimated);
      el.dataset.kind = model.kind;
      el.dataset.x0 = x0.toFixed(6);
      el.dataset.x1 = x1.toFixed(6);
    };

    // The worker path: a model change asks the worker; its answer is drawn at the next frame.
    let feed: PlotFeed | null = null;
    let drawnTraces = '';
    const draw = () => {
      frame = 0;
      const started = performance.now();
      if (!plot || shape() !== built) build();
      const u = plot as uPlot;
      if (feed && layout) {
        const r = feed.take();
        if (!r || drawnTraces !== built) {
          // Nothing new, or data for other traces than uPlot's now: ask, draw the answer.
          if (drawnTraces !== built) feed.request(columnsOf(u));
          drawnTraces = built;
          if (!r) return;
        }
        if (r.ys.length !== model.traces.length) return;
        layout.columns = r.decimated ? { off: r.off, count: r.count } : null;
        show(u, r.x, unpackYs(r.ys), r.window, r.points, r.decimated);
      } else {
        const d = model.plotData(columnsOf(u));
        show(u, d.x, d.ys, d.window, d.points, d.decimated);
      }
      model.drawMs += performance.now() - started;
    };
    const schedule = () => {
      if (!frame) frame = requestAnimationFrame(draw);
    };
    if (path === 'worker') feed = new PlotFeed(model, startPlotWorker(), schedule);
    // While following live samples, the view moves every animation frame (model.tick), not
    // only when a frame of samples arrives.
    model.smooth = path === 'worker';
    let ticking = 0;
    const tick = () => {
      model.tick();
      ticking = requestAnimationFrame(tick);
    };
    if (model.smooth) ticking = requestAnimationFrame(tick);
    const changed = () => {
      if (feed && plot) feed.request(columnsOf(plot));
      else schedule();
    };

    // Interactions on uPlot's plot area ("over").
    let detach = () => {};
    function attach(u: uPlot) {
      detach();
      const over = u.over;
      let pan: { x: number; moved: boolean } | null = null;
      let press: { x: number; y: number } | null = null;
      const secondsPerPx = () => {
        const [x0, x1] = model.window();
        return (x1 - x0) / Math.max(1, over.clientWidth);
      };
      const onDownCapture = (e: MouseEvent) => {
        if (e.button !== 0) return;
        if (e.shiftKey) {
          // Shift-drag pans: keep uPlot from starting a zoom selection.
          e.stopPropagation();
          e.preventDefault();
          pan = { x: e.clientX, moved: false };
          window.addEventListener('mousemove', onPanMove);
          window.addEventListener('mouseup', onPanUp);
        } else press = { x: e.clientX, y: e.clientY };
      };
      const onPanMove = (e: MouseEvent) => {
        if (!pan) return;
        const dx = e.clientX - pan.x;
        if (dx === 0) return;
        pan.x = e.clientX;
        pan.moved = true;
        model.pan(-dx * secondsPerPx());
      };
      const onPanUp = () => {
        pan = null;
        window.removeEventListener('mousemove', onPanMove);
        window.removeEventListener('mouseup', onPanUp);
      };
      const onUp = (e: MouseEvent) => {
        if (!press) return;
        const moved = Math.abs(e.clientX - press.x) + Math.abs(e.clientY - press.y) > 3;
        press = null;
        if (moved) return;
        const rect = over.getBoundingClientRect();
        placeRef.current(u.posToVal(e.clientX - rect.left, 'x'));
      };
      const onWheel = (e: WheelEvent) => {
        e.preventDefault();
        const unit = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? over.clientWidth : 1;
        if (e.ctrlKey || e.metaKey) {
          const rect = over.getBoundingClientRect();
          model.zoomAround(u.posToVal(e.clientX - rect.left, 'x'), 1.15 ** ((e.deltaY * unit) / 100));
        } else {
          const d = Math.abs(e.deltaX) > Math.abs(e.deltaY) ? e.deltaX : e.deltaY;
          model.pan(d * unit * secondsPerPx());
        }
      };
      el.addEventListener('mousedown', onDownCapture, true);
      over.addEventListener('mouseup', onUp);
      over.addEventListener('wheel', onWheel, { passive: false });
      detach = () => {
        el.removeEventListener('mousedown', onDownCapture, true);
        over.removeEventListener('mouseup', onUp);
        over.removeEventListener('wheel', onWheel);
        onPanUp();
      };
    }

    const png: PlotApi['png'] = (title, legend) => {
      const u = plot;
      if (!u) return Promise.resolve(null);
      const src = u.ctx.canvas;
      const px = uPlot.pxRatio;
      const line = 18 * px;
      const out = document.createElement('canvas');
      out.width = src.width;
      out.height = src.height + line * (legend.length + 1) + 10 * px;
      const ctx = out.getContext('2d');
      if (!ctx) return Promise.resolve(null);
      ctx.fillStyle = '#ffffff';
      ctx.fillRect(0, 0, out.width, out.height);
      ctx.fillStyle = '#1c2430';
      ctx.font = `bold ${12 * px}px system-ui, sans-serif`;
      ctx.fillText(title, 8 * px, 14 * px);
      ctx.drawImage(src, 0, line);
      ctx.font = `${11 * px}px ui-monospace, "DejaVu Sans Mono", monospace`;
      legend.forEach((row, i) => {
        const y = line + src.height + 6 * px + i * line;
        ctx.fillStyle = row.colour;
        ctx.fillRect(8 * px, y + 3 * px, 14 * px, 4 * px);
        ctx.fillStyle = '#1c2430';
        ctx.fillText(row.text, 28 * px, y + 9 * px);
      });
      return new Promise((resolve) => out.toBlob((b) => resolve(b), 'image/png'));
    };
    apiRef.current?.({ png });

    const unsub = model.subscribe(changed);
    const unsubTheme = themeState.subscribe(changed);
    const ro = new ResizeObserver(() => {
      if (plot && Math.abs(plot.width - widthOf()) > 1) {
        plot.setSize({ width: widthOf(), height });
        changed();
      }
    });
    ro.observe(el);
    draw();
    changed();
    return () => {
      unsub();
      unsubTheme();
      ro.disconnect();
      feed?.dispose();
      if (ticking) cancelAnimationFrame(ticking);
      model.smooth = false;
      if (frame) cancelAnimationFrame(frame);
      detach();
      plot?.destroy();
      plot = null;
      apiRef.current?.(null);
    };
  }, [model, height, overlay]);

  return <div className="scope-plot" ref={host} data-testid="scope-plot" />;
}
