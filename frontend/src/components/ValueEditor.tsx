/**
 * Write one object: an input in decimal or hex (the card web server takes hex, LECSN manual
 * §20.7), checked in the browser against the type range, the profile's min/max and the
 * enumeration before anything is sent, with the message in place; then PUT and the value the
 * drive reads back, or the refusal with its code, meaning, cause and remedy. While this tab
 * does not hold control of the drive (`blocked`: why), Write is disabled and says why.
 *
 * An object whose engineering unit differs from its raw one (rpm for inc/s, % for 0.1 %) is
 * entered in either: "Enter in rpm | raw (inc/s)", engineering by default and remembered by
 * the browser (lib/units.ts). An engineering value is converted to raw here, rounded to the
 * drive's whole step for an integer object and range-checked in both units; the raw value is
 * what is sent. Hex is a raw notation: choosing it enters raw.
 */
import { type FormEvent, useEffect, useRef, useState } from 'react';
import type { ErrorInfo, ObjectInfo, ObjectScalar, ObjectValue, ObjectWrite } from '../api/types';
import { type Failure, failureOf } from '../lib/codes';
import { type NumberMode, formatEngineering, isIntegerType, parseNumberInput, valueToInput } from '../lib/format';
import {
  type EntryUnit,
  bothRangesText,
  engineeringToRaw,
  loadEntryUnit,
  offersEngineeringEntry,
  parseEngineering,
  rawToEngText,
  saveEntryUnit,
  toRaw,
} from '../lib/units';
import { type WriteCheck, checkWrite, rangeText } from '../lib/validate';
import { decText, enumText, hexText } from '../lib/values';
import { FailureBox } from './FailureBox';

/** The browser's choice of entry units, shared by every editor and kept across reloads. */
export function useEntryUnit(): [EntryUnit, (u: EntryUnit) => void] {
  const [unit, setUnit] = useState<EntryUnit>(loadEntryUnit);
  return [
    unit,
    (u) => {
      saveEntryUnit(u);
      setUnit(u);
    },
  ];
}

/** The raw value a text means in the given entry, without range checks (for re-showing it). */
function rawOfText(obj: ObjectInfo, text: string, mode: NumberMode, entry: EntryUnit): number | null {
  if (entry === 'eng') {
    const p = parseEngineering(text);
    return p.ok ? toRaw(obj, p.value).raw : null;
  }
  const p = parseNumberInput(text, mode, obj.data_type);
  return p.ok ? p.value : null;
}

function textOfRaw(obj: ObjectInfo, raw: ObjectScalar, mode: NumberMode, entry: EntryUnit): string {
  return entry === 'eng' && typeof raw === 'number' ? rawToEngText(raw, obj) : valueToInput(raw, mode, obj.data_type);
}

export function ValueEditor({
  obj,
  current,
  mode,
  onMode,
  write,
  errors,
  onWritten,
  onCancel,
  autoFocus = false,
  blocked = null,
}: {
  obj: ObjectInfo;
  current: ObjectScalar | null | undefined;
  mode: NumberMode;
  onMode: (m: NumberMode) => void;
  write: (body: ObjectWrite) => Promise<ObjectValue>;
  errors: readonly ErrorInfo[];
  onWritten?: (v: ObjectValue) => void;
  onCancel?: () => void;
  autoFocus?: boolean;
  /** Why a write would be refused now (this tab does not hold control), or null. */
  blocked?: string | null;
}) {
  const [entryPref, setEntryPref] = useEntryUnit();
  const engOffered = offersEngineeringEntry(obj);
  // Engineering values are decimal: the hex base (here or on the page's toolbar) enters raw.
  const entry: EntryUnit = engOffered && mode === 'dec' && entryPref === 'eng' ? 'eng' : 'raw';
  const [text, setText] = useState(() => (current === null || current === undefined ? '' : textOfRaw(obj, current, mode, entry)));
  const [touched, setTouched] = useState(false);
  const [busy, setBusy] = useState(false);
  const [readBack, setReadBack] = useState<ObjectValue | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);

  const eng = entry === 'eng' ? engineeringToRaw(obj, text) : null;
  // The converted raw value still goes through the raw checks (access, type, enumeration).
  const check: WriteCheck = eng ? (eng.ok ? checkWrite(obj, String(eng.raw), 'dec') : { ok: false, message: eng.message, hint: eng.hint }) : checkWrite(obj, text, mode);
  const showCheck = touched && !check.ok;
  const hexAllowed = isIntegerType(obj.data_type);

  // The base or the entry units may change here or on the page's toolbar: convert what is
  // typed either way, so the value stays the same.
  const shown = useRef({ mode, entry });
  useEffect(() => {
    const from = shown.current;
    shown.current = { mode, entry };
    if (from.mode === mode && from.entry === entry) return;
    setText((t) => {
      const raw = rawOfText(obj, t, from.mode, from.entry);
      return raw === null ? t : textOfRaw(obj, raw, mode, entry);
    });
  }, [mode, entry, obj]);

  function switchMode(m: NumberMode) {
    if (m !== mode) onMode(m);
  }

  function switchEntry(u: EntryUnit) {
    if (u === 'eng' && mode !== 'dec') onMode('dec');
    if (u !== entryPref) setEntryPref(u);
  }

  async function submit(e: FormEvent) {
    e.preventDefault();
    setTouched(true);
    setReadBack(null);
    setFailure(null);
    if (!check.ok || blocked) return;
    setBusy(true);
    try {
      const v = await write(check.body);
      setReadBack(v);
      onWritten?.(v);
    } catch (err) {
      setFailure(failureOf(err, `Write ${obj.address}`, errors));
    } finally {
      setBusy(false);
    }
  }

  // What the typed value means, before it is written: engineering value and enumeration text.
  // Both units always: "3000 rpm = 491520 raw (inc/s)", or "491520 raw (inc/s) = 3000 rpm".
  let preview: string | null = null;
  if (check.ok && typeof check.value === 'number') {
    const parts: string[] = [];
    let decShown = true;
    if (eng?.ok) parts.push(eng.preview);
    else if (obj.unit && (obj.scale !== 1 || obj.raw_unit !== obj.unit)) {
      const raw = `${decText(check.value)} raw${obj.raw_unit ? ` (${obj.raw_unit})` : ''}`;
      parts.push(`${raw} = ${formatEngineering(check.value * obj.scale, obj.unit)}`);
    } else decShown = mode !== 'hex';
    const et = enumText(obj, check.value);
    if (et) parts.push(`“${et}”`);
    if (!decShown) parts.push(`= ${check.value} dec`);
    else if (hexAllowed) parts.push(`= ${hexText(check.value, obj.data_type)}`);
    preview = parts.join(' · ') || null;
  }

  return (
    <form className="value-editor" onSubmit={(e) => void submit(e)} data-testid="value-editor">
      <div className="ve-row">
        <label className="ve-label">
          {/* One flex item: the caption's unit stays on its line. */}
          <span data-testid="value-label">
            New value
            {entry === 'eng' ? (
              <span className="muted"> ({obj.unit})</span>
            ) : obj.raw_unit ? (
              <span className="muted"> (raw, {obj.raw_unit})</span>
            ) : (
              <span className="muted"> (raw)</span>
            )}
          </span>
          <input
            className={`mono${showCheck ? ' input-bad' : ''}`}
            data-testid="value-input"
            value={text}
            autoFocus={autoFocus}
            spellCheck={false}
            autoComplete="off"
            placeholder={entry === 'eng' ? `${obj.unit ?? ''}, e.g. 1500` : mode === 'hex' ? 'hex, e.g. 3E8' : 'decimal, e.g. 1000'}
            aria-invalid={showCheck}
            onChange={(e) => {
              setText(e.target.value);
              setTouched(true);
            }}
            onKeyDown={(e) => {
              if (e.key === 'Escape' && onCancel) onCancel();
            }}
          />
        </label>
        {engOffered && (
          <div className="ve-entry" data-testid="value-entry">
            <span className="small muted" id={`ve-entry-${obj.address}`}>
              Enter in
            </span>
            <div className="segmented" role="group" aria-labelledby={`ve-entry-${obj.address}`}>
              <button type="button" className={entry === 'eng' ? 'on' : ''} aria-pressed={entry === 'eng'} data-testid="entry-eng" onClick={() => switchEntry('eng')}>
                {obj.unit}
              </button>
              <button type="button" className={entry === 'raw' ? 'on' : ''} aria-pressed={entry === 'raw'} data-testid="entry-raw" onClick={() => switchEntry('raw')}>
                raw{obj.raw_unit ? ` (${obj.raw_unit})` : ''}
              </button>
            </div>
          </div>
        )}
        {hexAllowed && entry === 'raw' && (
          <div className="segmented" role="group" aria-label="Number base">
            <button type="button" className={mode === 'dec' ? 'on' : ''} aria-pressed={mode === 'dec'} data-testid="value-dec" onClick={() => switchMode('dec')}>
              Dec
            </button>
            <button type="button" className={mode === 'hex' ? 'on' : ''} aria-pressed={mode === 'hex'} data-testid="value-hex" onClick={() => switchMode('hex')}>
              Hex
            </button>
          </div>
        )}
        <button type="submit" className="primary" data-testid="value-write" disabled={busy || !!blocked} title={blocked ?? undefined}>
          {busy ? 'Writing…' : 'Write'}
        </button>
        {onCancel && (
          <button type="button" onClick={onCancel} data-testid="value-cancel">
            Close
          </button>
        )}
      </div>
      {blocked && (
        <div className="small warn-text" data-testid="value-blocked">
          Write is disabled: {blocked}.
        </div>
      )}
      <div className="ve-meta small muted">
        {obj.data_type}
        {entry === 'eng' ? (bothRangesText(obj) ? ` · allowed ${bothRangesText(obj)}` : '') : rangeText(obj, mode) ? ` · allowed ${rangeText(obj, mode)}` : ''}
        {obj.values && Object.keys(obj.values).length > 0 ? ` · ${Object.keys(obj.values).length} documented values` : ''}
      </div>
      {showCheck && !check.ok && (
        <div className="inline-error" role="alert" data-testid="value-error">
          {check.message}
          {check.hint ? <span className="ve-hint"> — {check.hint}</span> : null}
        </div>
      )}
      {check.ok && touched && (preview || check.note || (eng?.ok && eng.note)) && (
        <div className="small ve-preview" data-testid="value-preview">
          {preview}
          {eng?.ok && eng.note ? (
            <span className="warn-text ve-rounded" data-testid="value-rounded">
              {eng.note}
            </span>
          ) : null}
          {check.note ? <span className="warn-text"> {check.note}</span> : null}
        </div>
      )}
      {readBack && (
        <div className="readback" data-testid="readback">
          <span className="ok-mark">✓</span> Written; the drive reads back{' '}
          <strong className="mono" data-testid="readback-value">
            {decText(readBack.value)}
          </strong>
          {readBack.raw_unit ? <span className="unit"> {readBack.raw_unit}</span> : null}
          {hexText(readBack.value, readBack.data_type) !== '—' ? <span className="mono muted"> ({hexText(readBack.value, readBack.data_type)})</span> : null}
          {readBack.engineering !== null && readBack.unit ? <span className="mono"> = {formatEngineering(readBack.engineering, readBack.unit)}</span> : null}
          {readBack.value_text ? <span> “{readBack.value_text}”</span> : null}
        </div>
      )}
      {failure && <FailureBox f={failure} testid="write-failure" />}
    </form>
  );
}
