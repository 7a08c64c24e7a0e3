/**
 * Gains old -> new, with their units and the raw values the drive holds side by side, and the
 * object each one lives in. Without a result it lists the present gains.
 */
import type { GainLine } from './tuningModel';
import { changeText } from './tuningModel';

export function GainTable({ lines, compare, testid = 'tuning-gains' }: { lines: GainLine[]; compare: boolean; testid?: string }) {
  if (!lines.length) return <div className="muted">No gains to show.</div>;
  return (
    <table className="grid tuning-gains" data-testid={testid}>
      <thead>
        <tr>
          <th>Gain</th>
          <th>Object</th>
          {compare ? (
            <>
              <th className="num">Before</th>
              <th className="num">After</th>
              <th className="num">Change</th>
              <th className="num">Raw before → after</th>
            </>
          ) : (
            <>
              <th className="num">Value</th>
              <th className="num">Raw</th>
            </>
          )}
        </tr>
      </thead>
      <tbody>
        {lines.map((g) => (
          <tr key={g.object} data-testid={`gain-${g.name}`} className={compare && g.changed ? 'gain-changed' : undefined}>
            <th>{g.label}</th>
            <td className="mono muted small">{g.object}</td>
            {compare ? (
              <>
                <td className="mono num">
                  {g.before} <span className="unit">{g.unit}</span>
                </td>
                <td className="mono num" data-testid={`gain-${g.name}-after`}>
                  {g.after} <span className="unit">{g.unit}</span>
                </td>
                <td className="mono num small">{changeText(g.change)}</td>
                <td className="mono num small">
                  {g.rawBefore} → {g.rawAfter} <span className="unit">{g.rawUnit}</span>
                </td>
              </>
            ) : (
              <>
                <td className="mono num">
                  {g.before} <span className="unit">{g.unit}</span>
                </td>
                <td className="mono num small">
                  {g.rawBefore} <span className="unit">{g.rawUnit}</span>
                </td>
              </>
            )}
          </tr>
        ))}
      </tbody>
    </table>
  );
}
