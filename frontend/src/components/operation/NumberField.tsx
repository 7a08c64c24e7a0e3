/**
 * A numeric input of the Operation page in drive (raw) or engineering units, with the other
 * unit shown beside it, the limit that applies, and the problem the browser-side check found.
 * The value handed up is always raw: the API takes raw units.
 */
import { type ReactNode, useEffect, useState } from 'react';
import type { UnitInfo } from '../../api/types';
import {
  type EntryUnits,
  engUnitName,
  entryText,
  formatNumber,
  hasEngineering,
  parseEntry,
  rawUnitName,
  toEngineering,
} from '../../lib/motionLimits';

export interface RawField {
  raw: number | null;
  /** The text is not a number. */
  error: string | null;
}

export function useRawField(initial: number | null): [RawField, (raw: number | null, error: string | null) => void] {
  const [v, setV] = useState<RawField>({ raw: initial, error: null });
  return [v, (raw, error) => setV({ raw, error })];
}

export function NumberField({
  testid,
  label,
  unit,
  entry,
  field,
  onChange,
  problem,
  limit,
  optional = false,
  placeholder,
  title,
}: {
  testid: string;
  label: string;
  unit: UnitInfo | undefined;
  entry: EntryUnits;
  field: RawField;
  onChange: (raw: number | null, error: string | null) => void;
  problem?: string | null | undefined;
  limit?: ReactNode;
  optional?: boolean;
  placeholder?: string;
  title?: string;
}) {
  const shownUnit = entry === 'eng' ? engUnitName(unit) : rawUnitName(unit);
  const [text, setText] = useState(() => entryText(field.raw, entry, unit));

  // Re-show the value in the new units when the person switches raw <-> engineering.
  useEffect(() => {
    setText(entryText(field.raw, entry, unit));
  }, [entry, unit?.scale]);

  const other =
    field.raw === null || !hasEngineering(unit)
      ? null
      : entry === 'raw'
        ? `= ${formatNumber(toEngineering(field.raw, unit))} ${engUnitName(unit)}`
        : `= ${field.raw} ${rawUnitName(unit)}`;
  const message = field.error ?? problem ?? null;
  return (
    <label className={`op-field${message ? ' op-field-bad' : ''}`} title={title}>
      <span className="op-field-label">
        {label}
        {optional && <span className="muted"> (optional)</span>}
      </span>
      <span className="op-input">
        <input
          type="text"
          inputMode="decimal"
          className="mono"
          data-testid={testid}
          value={text}
          placeholder={placeholder ?? (optional ? 'drive value' : '')}
          aria-invalid={message ? true : undefined}
          onChange={(e) => {
            setText(e.target.value);
            const p = parseEntry(e.target.value, entry, unit);
            onChange(p.ok ? p.raw : null, p.ok ? null : p.error);
          }}
        />
        <span className="op-unit mono" title={shownUnit}>
          <span className="op-unit-text">{shownUnit}</span>
        </span>
      </span>
      <span className="op-conv mono muted" data-testid={`${testid}-conv`}>
        {other ?? '\u00a0'}
      </span>
      {limit && <span className="op-limit muted">{limit}</span>}
      {message && (
        <span className="op-problem" data-testid={`${testid}-problem`}>
          {message}
        </span>
      )}
    </label>
  );
}
