/**
 * Small inputs of the PDO editor: a number box that keeps what the person types until it is a
 * valid value (so "1" on the way to "10" does not jump), the problems next to a field, and the
 * bit budget as a bar.
 */
import { type ReactNode, useEffect, useState } from 'react';
import type { PdoProblem } from '../../api/types';

/** Problems shown in place, each with the clause it cites. */
export function ProblemList({ problems, testid }: { problems: readonly PdoProblem[] | undefined; testid: string }) {
  if (!problems?.length) return null;
  return (
    <ul className="pdo-problems" data-testid={testid} role="alert">
      {problems.map((p, i) => (
        <li key={i}>
          {p.message}
          {p.section ? <span className="muted small"> ({p.section})</span> : null}
        </li>
      ))}
    </ul>
  );
}

/**
 * A number input: `parse` turns the text into a value or null (invalid); valid text is handed
 * up at once, invalid text stays in the box marked red until it is fixed.
 */
export function NumberBox({
  value,
  onChange,
  parse,
  format = String,
  testid,
  label,
  disabled = false,
  width = 80,
  title,
}: {
  value: number;
  onChange: (v: number) => void;
  parse: (text: string) => number | null;
  format?: (v: number) => string;
  testid: string;
  label: string;
  disabled?: boolean;
  width?: number;
  title?: string;
}) {
  const [text, setText] = useState(() => format(value));
  // A value set from elsewhere (template, revert) replaces the text unless it already means it.
  useEffect(() => {
    setText((t) => (parse(t) === value ? t : format(value)));
    // parse/format are stable per field; value is what matters.
  }, [value]);
  const bad = parse(text) === null;
  return (
    <input
      type="text"
      inputMode="decimal"
      className={`mono${bad ? ' pdo-bad-input' : ''}`}
      style={{ width }}
      value={text}
      disabled={disabled}
      aria-label={label}
      aria-invalid={bad}
      title={bad ? `not a valid ${label.toLowerCase()}` : title}
      data-testid={testid}
      onChange={(e) => {
        setText(e.target.value);
        const v = parse(e.target.value);
        if (v !== null && v !== value) onChange(v);
      }}
      onBlur={() => {
        if (parse(text) !== null) setText(format(value));
      }}
    />
  );
}

/** An integer in [min, max], decimal. */
export function intParser(min: number, max: number): (text: string) => number | null {
  return (text) => {
    if (!/^\s*\d+\s*$/.test(text)) return null;
    const v = Number.parseInt(text, 10);
    return v >= min && v <= max ? v : null;
  };
}

/** A decimal number in [min, max] with at most `decimals` places. */
export function decimalParser(min: number, max: number, decimals: number): (text: string) => number | null {
  const re = new RegExp(`^\\s*\\d+(?:[.,]\\d{0,${decimals}})?\\s*$`);
  return (text) => {
    if (!re.test(text)) return null;
    const v = Number.parseFloat(text.replace(',', '.'));
    return Number.isFinite(v) && v >= min && v <= max ? v : null;
  };
}

/** A bar: used against max, red when over; `label` says it in words. */
export function BudgetBar({ used, max, label, testid, over }: { used: number; max: number; label: ReactNode; testid: string; over: boolean }) {
  const pct = max > 0 ? Math.min(100, (used / max) * 100) : 0;
  return (
    <div className={`pdo-budget${over ? ' over' : ''}`} data-testid={testid} data-used={used} data-max={max}>
      <div
        className="pdo-budget-track"
        role="meter"
        aria-valuemin={0}
        aria-valuemax={max}
        aria-valuenow={used}
        aria-label={typeof label === 'string' ? label : undefined}
      >
        <div className="pdo-budget-fill" style={{ width: `${pct}%` }} />
      </div>
      <span className="pdo-budget-label small">{label}</span>
    </div>
  );
}
