/**
 * Per-trace measurements of the visible range (min, max, mean, RMS, frequency, samples and
 * rate) and the values at the two cursors with delta-t and 1/delta-t; every value shown
 * (engineering x scale + offset, with its unit) above the raw value (muted, raw unit).
 */
import type { CursorValue, TraceDef, TraceStats } from './model';
import type { Stats } from './stats';
import { hz, num, secs, withUnit } from './format';

export interface MeasureSummary {
  window: [number, number];
  stats: TraceStats[];
  a: CursorValue[] | null;
  b: CursorValue[] | null;
  cursorA: number | null;
  cursorB: number | null;
}

function Pair({ shown, raw, unit, rawUnit, testid }: { shown: number | null; raw: number | null; unit: string; rawUnit: string; testid?: string }) {
  return (
    <td className="mono scope-pair" data-testid={testid} data-shown={shown ?? ''} data-raw={raw ?? ''}>
      <div>{withUnit(num(shown), shown === null ? '' : unit)}</div>
      <div className="muted">{raw === null ? '' : withUnit(num(raw, 8), rawUnit || 'raw')}</div>
    </td>
  );
}

interface Props {
  traces: readonly TraceDef[];
  summary: MeasureSummary;
  onToggle: (key: string) => void;
}

export function Measurements({ traces, summary, onToggle }: Props) {
  const byKey = new Map(summary.stats.map((s) => [s.key, s]));
  const at = (list: CursorValue[] | null, key: string) => list?.find((c) => c.key === key) ?? null;
  const { cursorA, cursorB } = summary;
  const dt = cursorA !== null && cursorB !== null ? cursorB - cursorA : null;
  const stat = (s: Stats | undefined, f: keyof Stats) => (s ? (s[f] as number | null) : null);
  return (
    <div className="scope-measure" data-testid="scope-measurements">
      <div className="scope-row small">
        <span>
          Visible range <span className="mono">{secs(summary.window[0])}</span> … <span className="mono">{secs(summary.window[1])}</span>
        </span>
        <span data-testid="scope-cursor-a" data-t={cursorA ?? ''}>
          Cursor A <span className="mono">{cursorA === null ? '—' : secs(cursorA)}</span>
        </span>
        <span data-testid="scope-cursor-b" data-t={cursorB ?? ''}>
          Cursor B <span className="mono">{cursorB === null ? '—' : secs(cursorB)}</span>
        </span>
        <span data-testid="scope-cursor-dt" data-dt={dt ?? ''}>
          Δt <span className="mono">{secs(dt)}</span> · 1/Δt <span className="mono">{dt ? hz(1 / Math.abs(dt)) : '—'}</span>
        </span>
      </div>
      <table className="grid scope-grid">
        <thead>
          <tr>
            <th />
            <th>Trace</th>
            <th title="samples in the visible range, and their rate">Samples</th>
            <th>Min</th>
            <th>Max</th>
            <th>Mean</th>
            <th>RMS</th>
            <th title="from the crossings of the mean">Frequency</th>
            <th>At A</th>
            <th>At B</th>
            <th>B − A</th>
          </tr>
          <tr className="scope-subhead">
            <th colSpan={3} />
            <th colSpan={8} className="muted small">
              each cell: shown value (engineering × scale + offset) above, raw value below
            </th>
          </tr>
        </thead>
        <tbody>
          {traces.map((t) => {
            const s = byKey.get(t.key);
            const va = at(summary.a, t.key);
            const vb = at(summary.b, t.key);
            return (
              <tr key={t.key} data-testid={`scope-stats-${t.key}`} data-n={s?.shown.n ?? 0} className={t.visible ? '' : 'scope-hidden-row'}>
                <td>
                  <input type="checkbox" checked={t.visible} onChange={() => onToggle(t.key)} title="show this trace" data-testid={`scope-trace-${t.key}-visible`} />
                  <span className="scope-swatch" style={{ background: t.colour }} />
                </td>
                <td>
                  {t.label}
                  <span className="muted small"> {t.unit ? `[${t.unit}]` : ''}</span>
                </td>
                <td className="mono">
                  <div>{s?.shown.n ?? 0}</div>
                  <div className="muted">{hz(s?.shown.rateHz)}</div>
                </td>
                <Pair shown={stat(s?.shown, 'min')} raw={stat(s?.raw, 'min')} unit={t.unit} rawUnit={t.rawUnit} testid={`scope-stats-${t.key}-min`} />
                <Pair shown={stat(s?.shown, 'max')} raw={stat(s?.raw, 'max')} unit={t.unit} rawUnit={t.rawUnit} testid={`scope-stats-${t.key}-max`} />
                <Pair shown={stat(s?.shown, 'mean')} raw={stat(s?.raw, 'mean')} unit={t.unit} rawUnit={t.rawUnit} />
                <Pair shown={stat(s?.shown, 'rms')} raw={stat(s?.raw, 'rms')} unit={t.unit} rawUnit={t.rawUnit} />
                <td className="mono" data-testid={`scope-stats-${t.key}-freq`}>
                  {hz(s?.shown.freqHz)}
                </td>
                <Pair shown={va?.shown ?? null} raw={va?.raw ?? null} unit={t.unit} rawUnit={t.rawUnit} testid={`scope-at-a-${t.key}`} />
                <Pair shown={vb?.shown ?? null} raw={vb?.raw ?? null} unit={t.unit} rawUnit={t.rawUnit} testid={`scope-at-b-${t.key}`} />
                <Pair
                  shown={va && vb ? vb.shown - va.shown : null}
                  raw={va && vb ? vb.raw - va.raw : null}
                  unit={t.unit}
                  rawUnit={t.rawUnit}
                />
              </tr>
            );
          })}
          {traces.length === 0 && (
            <tr>
              <td colSpan={11} className="muted">
                Nothing to measure yet.
              </td>
            </tr>
          )}
        </tbody>
      </table>
    </div>
  );
}
