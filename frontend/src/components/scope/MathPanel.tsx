/**
 * Math channels (difference, sum, derivative of channels), computed in the browser on the
 * shown values; kept in this browser with the colours.
 */
import { type MathOp, needsSecond } from './math';
import { MAX_MATH, type MathDef } from './prefs';

const OPS: { id: MathOp; text: string }[] = [
  { id: 'diff', text: 'A − B (difference)' },
  { id: 'sum', text: 'A + B (sum)' },
  { id: 'deriv', text: 'dA/dt (derivative)' },
];

interface Props {
  maths: readonly MathDef[];
  channels: readonly { id: number; label: string }[];
  onChange: (id: number, patch: Partial<MathDef>) => void;
  onAdd: () => void;
  onRemove: (id: number) => void;
}

export function MathPanel({ maths, channels, onChange, onAdd, onRemove }: Props) {
  const chanSelect = (value: number | null, onPick: (id: number) => void, testid: string) => (
    <select value={value ?? ''} onChange={(e) => onPick(Number(e.target.value))} data-testid={testid}>
      {(value === null || !channels.some((c) => c.id === value)) && <option value={value ?? ''}>{value === null ? 'choose…' : `channel ${value} (none)`}</option>}
      {channels.map((c) => (
        <option key={c.id} value={c.id}>
          {c.id} · {c.label}
        </option>
      ))}
    </select>
  );
  return (
    <div className="scope-math" data-testid="scope-math">
      {maths.map((m) => (
        <div key={m.id} className="scope-row" data-testid={`scope-math-${m.id}`}>
          <input type="checkbox" checked={m.visible} onChange={(e) => onChange(m.id, { visible: e.target.checked })} title="show" />
          <input type="color" className="scope-colour" value={m.colour} onChange={(e) => onChange(m.id, { colour: e.target.value })} title="colour" />
          <span className="mono">M{m.id}</span>
          <select value={m.op} onChange={(e) => onChange(m.id, { op: e.target.value as MathOp })} data-testid={`scope-math-${m.id}-op`}>
            {OPS.map((o) => (
              <option key={o.id} value={o.id}>
                {o.text}
              </option>
            ))}
          </select>
          <span className="muted small">A</span>
          {chanSelect(m.a, (a) => onChange(m.id, { a }), `scope-math-${m.id}-a`)}
          {needsSecond(m.op) && (
            <>
              <span className="muted small">B</span>
              {chanSelect(m.b, (b) => onChange(m.id, { b }), `scope-math-${m.id}-b`)}
            </>
          )}
          <button type="button" className="small-btn" onClick={() => onRemove(m.id)} title="remove" data-testid={`scope-math-${m.id}-remove`}>
            ×
          </button>
        </div>
      ))}
      <div className="scope-row">
        <button type="button" onClick={onAdd} disabled={maths.length >= MAX_MATH || channels.length === 0} data-testid="scope-add-math">
          Add math channel
        </button>
        <span className="muted small">
          Two-channel results are at A's sample times with B interpolated; never extrapolated.
        </span>
      </div>
    </div>
  );
}
