/**
 * A small uPlot chart of actual position and velocity over the last seconds, fed from the
 * live store. Redraws are batched to one per animation frame so a 20 Hz state stream costs
 * at most one draw per frame.
 */
import { useEffect, useRef } from 'react';
import uPlot from 'uplot';
import { HISTORY_SECONDS, type LiveSession } from '../state/store';
import { useObservable, type Observable } from '../state/observable';
import { plotColors, themeState } from '../lib/theme';

interface Props {
  source: Observable<LiveSession>;
  positionUnit: string;
  velocityUnit: string;
}

export function LivePlot({ source, positionUnit, velocityUnit }: Props) {
  const host = useRef<HTMLDivElement | null>(null);
  const theme = useObservable(themeState).theme;

  useEffect(() => {
    const el = host.current;
    if (!el) return;
    const c = plotColors();
    const opts: uPlot.Options = {
      width: Math.max(200, el.clientWidth),
      height: 190,
      legend: { show: true, live: false },
      cursor: { drag: { x: false, y: false } },
      scales: { x: { time: false } },
      series: [
        { label: 't' },
        { label: `Position [${positionUnit}]`, scale: 'pos', stroke: c.accent, width: 1.5 },
        { label: `Velocity [${velocityUnit}]`, scale: 'vel', stroke: '#c25b12', width: 1.5 },
      ],
      axes: [
        {
          stroke: c.axis,
          grid: { stroke: c.grid, width: 1 },
          ticks: { stroke: c.ticks, width: 1 },
          values: (_u, ticks) => ticks.map((v) => `${v.toFixed(0)} s`),
          font: '11px ui-monospace, "DejaVu Sans Mono", monospace',
        },
        {
          scale: 'pos',
          stroke: c.accent,
          grid: { stroke: c.grid, width: 1 },
          font: '11px ui-monospace, "DejaVu Sans Mono", monospace',
          size: 64,
        },
        {
          scale: 'vel',
          side: 1,
          stroke: '#c25b12',
          grid: { show: false },
          font: '11px ui-monospace, "DejaVu Sans Mono", monospace',
          size: 64,
        },
      ],
    };
    const plot = new uPlot(opts, [[], [], []], el);
    let frame = 0;
    const draw = () => {
      frame = 0;
      const h = source.get().history;
      const now = Date.now() / 1000;
      // Time axis in seconds relative to now: -10 .. 0, so the newest sample sits at the right.
      const t = h.t.map((x) => x - now);
      plot.setData([t, h.position, h.velocity], false);
      plot.setScale('x', { min: -HISTORY_SECONDS, max: 0 });
    };
    const schedule = () => {
      if (!frame) frame = requestAnimationFrame(draw);
    };
    const unsub = source.subscribe(schedule);
    // States arrive only when something changes (at least once a second); keep the time axis
    // moving between them.
    const tick = setInterval(schedule, 250);
    const ro = new ResizeObserver(() => plot.setSize({ width: Math.max(200, el.clientWidth), height: 190 }));
    ro.observe(el);
    draw();
    return () => {
      unsub();
      clearInterval(tick);
      ro.disconnect();
      if (frame) cancelAnimationFrame(frame);
      plot.destroy();
    };
  }, [source, positionUnit, velocityUnit, theme]);

  return <div className="live-plot" ref={host} data-testid="live-plot" />;
}
