/**
 * Write one object: an input in decimal or hex (the card web server takes hex, LECSN manual
 * §20.7), checked in the browser against the type range, the profile's min/max and the
 * enumeration before anything is sent, with the message in place; then PUT and the value the
 * drive reads back, or the refusal with its code, meaning, cause and remedy. While this tab
 * does not hold control of the drive (`blocked`: why), Write is disabled and says why.
 */
import { type FormEvent, useEffect, useRef, useState } from 'react';
import type { ErrorInfo, ObjectInfo, ObjectScalar, ObjectValue, ObjectWrite } from '../api/types';
import { type Failure, failureOf } from '../lib/codes';
import { type NumberMode, formatEngineering, isIntegerType, parseNumberInput, valueToInput } from '../lib/format';
import { checkWrite, rangeText } from '../lib/validate';
import { decText, enumText, hexText } from '../lib/values';
import { FailureBox } from './FailureBox';

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
  const [text, setText] = useState(() => (current === null || current === undefined ? '' : valueToInput(current, mode, obj.data_type)));
  const [touched, setTouched] = useState(false);
  const [busy, setBusy] = useState(false);
  const [readBack, setReadBack] = useState<ObjectValue | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);

  const check = checkWrite(obj, text, mode);
  const showCheck = touched && !check.ok;
  const hexAllowed = isIntegerType(obj.data_type);

  // The base may change here or on the page's toolbar: convert what is typed either way.
  const shownMode = useRef(mode);
  useEffect(() => {
    const from = shownMode.current;
    shownMode.current = mode;
    if (from === mode) return;
    setText((t) => {
      const parsed = parseNumberInput(t, from, obj.data_type);
      return parsed.ok ? valueToInput(parsed.value, mode, obj.data_type) : t;
    });
  }, [mode, obj.data_type]);

  function switchMode(m: NumberMode) {
    if (m !== mode) onMode(m);
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
  let preview: string | null = null;
  if (check.ok && typeof check.value === 'number') {
    const parts: string[] = [];
    if (obj.unit && (obj.scale !== 1 || obj.raw_unit !== obj.unit)) parts.push(`= ${formatEngineering(check.value * obj.scale, obj.unit)}`);
    const et = enumText(obj, check.value);
    if (et) parts.push(`“${et}”`);
    if (mode === 'hex') parts.push(`= ${check.value} dec`);
    else if (hexAllowed) parts.push(`= ${hexText(check.value, obj.data_type)}`);
    preview = parts.join(' · ') || null;
  }

  return (
    <form className="value-editor" onSubmit={(e) => void submit(e)} data-testid="value-editor">
      <div className="ve-row">
        <label className="ve-label">
          New value{obj.raw_unit ? <span className="muted"> (raw, {obj.raw_unit})</span> : <span className="muted"> (raw)</span>}
          <input
            className={`mono${showCheck ? ' input-bad' : ''}`}
            data-testid="value-input"
            value={text}
            autoFocus={autoFocus}
            spellCheck={false}
            autoComplete="off"
            placeholder={mode === 'hex' ? 'hex, e.g. 3E8' : 'decimal, e.g. 1000'}
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
        {hexAllowed && (
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
        {rangeText(obj, mode) ? ` · allowed ${rangeText(obj, mode)}` : ''}
        {obj.values && Object.keys(obj.values).length > 0 ? ` · ${Object.keys(obj.values).length} documented values` : ''}
      </div>
      {showCheck && !check.ok && (
        <div className="inline-error" role="alert" data-testid="value-error">
          {check.message}
          {check.hint ? <span className="ve-hint"> — {check.hint}</span> : null}
        </div>
      )}
      {check.ok && touched && (preview || check.note) && (
        <div className="small ve-preview" data-testid="value-preview">
          {preview}
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
