/**
 * The Tuning page's plots on uPlot: the step responses before and after tuning overlaid (time
 * in ms, position in the drive's units relative to the start, the commanded step dashed), and
 * the Bode plot (log frequency; magnitude and phase, measured and model) when a result has one.
 * Each chart is built once per data set and resized with its box.
 */
import { useEffect, useRef } from 'react';
import uPlot from 'uplot';
import type { Bode, StepResponse } from '../../api/tuning';
import { plotColors, themeState } from '../../lib/theme';
import { useObservable } from '../../state/observable';
import { bodeSeries, decadeLabel, stepSeries } from './tuningModel';

const FONT = '11px ui-monospace, "DejaVu Sans Mono", monospace';
const BEFORE = '#8a8f98';
const MODEL = '#c25b12';
// The theme's colours at the time a chart is made (useChart makes it again on a change).
const grid = () => ({ stroke: plotColors().grid, width: 1 });
const axis = () => plotColors().axis;
const afterColor = () => plotColors().accent;

/** Build a chart in ``host`` and keep it sized to it; destroys it on change. */
function useChart(make: (el: HTMLDivElement, width: number) => uPlot | null, deps: unknown[]): React.MutableRefObject<HTMLDivElement | null> {
  const host = useRef<HTMLDivElement | null>(null);
  const theme = useObservable(themeState).theme;
  useEffect(() => {
    const el = host.current;
    if (!el) return;
    const plot = make(el, Math.max(240, el.clientWidth));
    if (!plot) return;
    const ro = new ResizeObserver(() => plot.setSize({ width: Math.max(240, el.clientWidth), height: plot.height }));
    ro.observe(el);
    return () => {
      ro.disconnect();
      plot.destroy();
    };
    // The data objects are the dependencies, and the theme (canvas colours are not CSS).
  }, [...deps, theme]);
  return host;
}

export function StepPlot({ before, after }: { before: StepResponse | null; after: StepResponse | null }) {
  const unit = (before ?? after)?.unit ?? '';
  const host = useChart(
    (el, width) => {
      if (!before && !after) return null;
      const data = stepSeries(before, after) as uPlot.AlignedData;
      return new uPlot(
        {
          width,
          height: 220,
          legend: { show: true, live: false },
          cursor: { drag: { x: true, y: false } },
          scales: { x: { time: false } },
          series: [
            { label: 't [ms]' },
            { label: 'before', stroke: BEFORE, width: 1.5, spanGaps: true },
            { label: 'after', stroke: afterColor(), width: 2, spanGaps: true },
            { label: 'step command', stroke: '#3a3', width: 1, dash: [6, 4] },
          ],
          axes: [
            { stroke: axis(), grid: grid(), font: FONT, values: (_u, t) => t.map((v) => `${v} ms`) },
            { stroke: axis(), grid: grid(), font: FONT, size: 70, label: unit, labelFont: FONT },
          ],
        },
        data,
        el,
      );
    },
    [before, after, unit],
  );
  return <div className="tuning-plot" ref={host} data-testid="tuning-step-plot" />;
}

function bodeChart(el: HTMLDivElement, width: number, freq: number[], cols: (number | null)[][], what: 'mag' | 'phase'): uPlot {
  return new uPlot(
    {
      width,
      height: 180,
      legend: { show: true, live: false },
      cursor: { drag: { x: true, y: false } },
      scales: { x: { time: false, distr: 3, log: 10 } },
      series: [
        { label: 'f [Hz]' },
        { label: `measured ${what === 'mag' ? 'magnitude' : 'phase'}`, stroke: afterColor(), width: 1.5, spanGaps: false },
        { label: 'model', stroke: MODEL, width: 1.5, dash: [5, 3], spanGaps: false },
      ],
      axes: [
        { stroke: axis(), grid: grid(), font: FONT, values: (_u, t) => t.map((v) => decadeLabel(v)) },
        { stroke: axis(), grid: grid(), font: FONT, size: 60, label: what === 'mag' ? 'dB' : 'deg', labelFont: FONT },
      ],
    },
    [freq, ...cols] as uPlot.AlignedData,
    el,
  );
}

export function BodePlot({ bode }: { bode: Bode }) {
  const s = bodeSeries(bode);
  const magHost = useChart((el, width) => (s.freq.length ? bodeChart(el, width, s.freq, s.mag, 'mag') : null), [bode]);
  const phaseHost = useChart((el, width) => (s.freq.length ? bodeChart(el, width, s.freq, s.phase, 'phase') : null), [bode]);
  return (
    <div data-testid="tuning-bode">
      <div className="tuning-plot" ref={magHost} />
      <div className="tuning-plot" ref={phaseHost} />
    </div>
  );
}

