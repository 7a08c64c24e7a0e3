/**
 * Object access: read or write one object dictionary entry by address (0x6040, 0x6040:00,
 * 6040h.0, P24640). A result shows name, type, access, the value in decimal and hex, the raw
 * bytes on the bus, the engineering value with its unit and the enumeration text. A failure
 * shows what failed, why (the message, the protocol's abort code in hex and its meaning) and
 * what to do. The last accesses stay in a history list.
 *
 * An object of the session's profile whose engineering unit differs from its raw one is
 * entered in either ("Enter in rpm | raw (inc/s)", the browser's choice as on Parameters;
 * lib/units.ts): an engineering value is converted to raw, rounded and range-checked in
 * both units before the raw value is sent.
 *
 * The typed value keeps the unit it was typed in. A new address whose object takes the same
 * unit keeps the number and previews it with that object's scale (3000 rpm stays 3000 rpm,
 * its inc/s are worked out again); one in another unit, or raw, does not re-read the number
 * in its own unit (3000 rpm is no 3000 deg, nor 3000 raw): the value is held, not previewed
 * and not sent, with a note to type it again, until the address is one of its unit again.
 */
import { type FormEvent, useMemo, useRef, useState } from 'react';
import type { ObjectInfo, ObjectValue, ObjectWrite } from '../api';
import { ApiError, api } from '../api/client';
import { ControlNote, useWriteGate } from '../components/ControlNote';
import { useEntryUnit } from '../components/ValueEditor';
import { formatAddress, parseAddress } from '../lib/address';
import { canonicalAddress } from '../lib/dictionary';
import {
  type NumberMode,
  formatEngineering,
  formatRawBytes,
  isBytesType,
  isStringType,
  parseNumberInput,
  toDec,
  toHex,
  valueToInput,
} from '../lib/format';
import { type EntryUnit, type TypedIn, engineeringToRaw, heldValueNote, offersEngineeringEntry, parseEngineering, rawToEngText, toRaw } from '../lib/units';
import { protocolName } from '../state/notify';
import { useSessionInfo, useSessionProfile } from '../state/profileCache';
import './dataPages.css';
import type { PageProps } from './registry';

interface Failure {
  /** What failed, e.g. "Write 0x6041:00". */
  action: string;
  message: string;
  code_hex: string | null;
  meaning: string | null;
  protocol: string | null;
  hint: string | null;
}

interface HistoryEntry {
  id: number;
  time: Date;
  op: 'R' | 'W';
  address: string;
  result: ObjectValue | null;
  failure: Failure | null;
  /** What was written, as typed. */
  written: string | null;
}

const HISTORY_LENGTH = 25;

const QUICK: ReadonlyArray<{ addr: string; name: string }> = [
  { addr: '0x6041:00', name: 'Statusword' },
  { addr: '0x6040:00', name: 'Controlword' },
  { addr: '0x6061:00', name: 'Mode display' },
  { addr: '0x6064:00', name: 'Position actual' },
  { addr: '0x606C:00', name: 'Velocity actual' },
  { addr: '0x6081:00', name: 'Profile velocity' },
  { addr: '0x603F:00', name: 'Error code' },
  { addr: '0x1018:01', name: 'Vendor id' },
];

function failureOf(e: unknown, action: string): Failure {
  if (e instanceof ApiError) {
    return {
      action: e.action,
      message: e.body.message,
      code_hex: e.body.code_hex ?? (e.body.code != null ? toHex(e.body.code, 'UNSIGNED32') : null),
      meaning: e.body.meaning ?? null,
      protocol: e.body.protocol ?? null,
      hint: e.body.hint ?? null,
    };
  }
  return {
    action,
    message: e instanceof Error ? e.message : String(e),
    code_hex: null,
    meaning: null,
    protocol: null,
    hint: null,
  };
}

function valueCells(v: ObjectValue): { dec: string; hex: string } {
  const value = v.value;
  if (typeof value === 'number') {
    return { dec: toDec(value), hex: Number.isInteger(value) ? toHex(value, v.data_type) : '—' };
  }
  if (typeof value === 'boolean') return { dec: value ? '1 (true)' : '0 (false)', hex: value ? '0x01' : '0x00' };
  if (value === null) return { dec: '—', hex: '—' };
  return { dec: value, hex: '—' };
}

function ResultView({ v }: { v: ObjectValue }) {
  const cells = valueCells(v);
  const eng = v.engineering !== null && v.unit ? formatEngineering(v.engineering, v.unit) : null;
  return (
    <table className="kv result" data-testid="object-result">
      <tbody>
        <tr>
          <th>Object</th>
          <td>
            <span className="mono" data-testid="object-result-address">
              {v.address}
            </span>{' '}
            <strong data-testid="object-name">{v.name ?? 'not in the profile'}</strong>
          </td>
        </tr>
        <tr>
          <th>Type · access</th>
          <td className="mono">
            <span data-testid="object-type">{v.data_type ?? '—'}</span> ·{' '}
            <span data-testid="object-access">{v.access ?? '—'}</span>
          </td>
        </tr>
        <tr>
          <th>Value (decimal)</th>
          <td className="mono big" data-testid="object-value-dec">
            {cells.dec}
            {v.raw_unit && typeof v.value === 'number' ? <span className="unit"> {v.raw_unit}</span> : null}
          </td>
        </tr>
        <tr>
          <th>Value (hex)</th>
          <td className="mono big" data-testid="object-value-hex">
            {cells.hex}
          </td>
        </tr>
        <tr>
          <th>Raw bytes (bus order)</th>
          <td className="mono" data-testid="object-raw">
            {formatRawBytes(v.raw_hex)}
          </td>
        </tr>
        <tr>
          <th>Engineering value</th>
          <td className="mono" data-testid="object-engineering">
            {eng ?? <span className="muted">— (no unit in the profile)</span>}
          </td>
        </tr>
        <tr>
          <th>Meaning</th>
          <td data-testid="object-value-text">{v.value_text ?? <span className="muted">—</span>}</td>
        </tr>
      </tbody>
    </table>
  );
}

function FailureView({ f }: { f: Failure }) {
  return (
    <div className="failure" data-testid="object-error" role="alert">
      <div className="failure-title">{f.action} failed</div>
      <div data-testid="object-error-message">{f.message}</div>
      {(f.code_hex || f.meaning) && (
        <div className="failure-code">
          {f.protocol ? `${protocolName(f.protocol)} ` : ''}
          {f.code_hex && (
            <span className="mono" data-testid="object-error-code">
              {f.code_hex}
            </span>
          )}
          {f.meaning && (
            <>
              {': '}
              <span data-testid="object-error-meaning">{f.meaning}</span>
            </>
          )}
        </div>
      )}
      {f.hint && (
        <div className="notice-hint" data-testid="object-error-hint">
          <span className="hint-label">What to do:</span> {f.hint}
        </div>
      )}
    </div>
  );
}

export function ObjectAccessPage({ sid }: PageProps) {
  const [address, setAddress] = useState('0x6041:00');
  const [valueText, setValueText] = useState('');
  const [mode, setMode] = useState<NumberMode>('dec');
  const [busy, setBusy] = useState<'read' | 'write' | null>(null);
  const gate = useWriteGate(sid, { write: 'write_parameters' });
  // Writes need control; the controlword (6040h) energises the drive, so it also needs this
  // tab's WebSocket bound as the dead-man (docs/api.md "Control and motion as built").
  const parsedForGate = parseAddress(address);
  const blocked = parsedForGate.ok && parsedForGate.address.index === 0x6040 ? gate.energise : gate.write;
  const [result, setResult] = useState<ObjectValue | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [history, setHistory] = useState<HistoryEntry[]>([]);
  const nextId = useRef(1);
  /** Data types learnt from reads, so hex input and range checks know the type before a write. */
  const types = useRef(new Map<string, string>());
  const { info } = useSessionInfo(sid);
  const { profile } = useSessionProfile(info);
  /** The session's objects by address: their units and scales (the session's own). */
  const objects = useMemo(() => new Map((profile?.object_list ?? []).map((o) => [canonicalAddress(o.address), o])), [profile]);
  const [entryPref, setEntryPref] = useEntryUnit();

  function objectAt(addr: string): ObjectInfo | null {
    const p = parseAddress(addr);
    return p.ok ? (objects.get(formatAddress(p.address)) ?? null) : null;
  }
  /** Engineering entry for this object in this base: decimal only (hex is raw). */
  function entryFor(o: ObjectInfo | null, m: NumberMode, pref: EntryUnit = entryPref): EntryUnit {
    return o && offersEngineeringEntry(o) && m === 'dec' && pref === 'eng' ? 'eng' : 'raw';
  }
  const obj = objectAt(address);
  const entry = entryFor(obj, mode);
  /** The unit this address is entered in now (null: raw). */
  const unitNow = entry === 'eng' && obj ? (obj.unit ?? '') : null;
  const addressNow = parsedForGate.ok ? formatAddress(parsedForGate.address) : address.trim();
  const [typedIn, setTypedIn] = useState<TypedIn>({ unit: null, address: addressNow });
  // A number typed for an object in another unit is held, never previewed or sent in this one.
  const held = heldValueNote(valueText, typedIn, unitNow, addressNow, obj?.raw_unit ?? null);
  const engCheck = entry === 'eng' && obj && valueText.trim() !== '' && held === null ? engineeringToRaw(obj, valueText) : null;

  function record(e: Omit<HistoryEntry, 'id' | 'time'>) {
    const entry: HistoryEntry = { ...e, id: nextId.current++, time: new Date() };
    setHistory((h) => [entry, ...h].slice(0, HISTORY_LENGTH));
  }

  function parsedAddress(): string | null {
    const p = parseAddress(address);
    if (!p.ok) {
      setResult(null);
      setFailure({ action: 'Address', message: p.message, code_hex: null, meaning: null, protocol: null, hint: p.hint });
      return null;
    }
    return formatAddress(p.address);
  }

  function show(v: ObjectValue, m: NumberMode = mode) {
    setResult(v);
    setFailure(null);
    if (v.data_type) types.current.set(v.address, v.data_type);
    const o = objectAt(v.address);
    if (o && entryFor(o, m) === 'eng' && typeof v.value === 'number') {
      setValueText(rawToEngText(v.value, o));
      setTypedIn({ unit: o.unit ?? '', address: v.address });
    } else {
      setValueText(valueToInput(v.value, m, v.data_type));
      setTypedIn({ unit: null, address: v.address });
    }
  }

  async function read(addrOverride?: string) {
    const addr = addrOverride ?? parsedAddress();
    if (!addr) return;
    setBusy('read');
    try {
      const v = await api.readObject(sid, addr);
      show(v);
      record({ op: 'R', address: v.address, result: v, failure: null, written: null });
    } catch (e) {
      const f = failureOf(e, `Read ${addr}`);
      setResult(null);
      setFailure(f);
      record({ op: 'R', address: addr, result: null, failure: f, written: null });
    } finally {
      setBusy(null);
    }
  }

  async function write() {
    const addr = parsedAddress();
    if (!addr) return;
    setBusy('write');
    let written = valueText;
    try {
      // Refused before anything is sent, as a value that does not convert is.
      if (held !== null) throw new ApiError(`Write ${addr}`, 400, { error: 'ValidationError', message: held });
      let dataType = types.current.get(addr) ?? null;
      if (!dataType) {
        // Learn the type first so hex input and range checks are right; a write-only object
        // cannot be read, and then the server validates alone.
        try {
          const v = await api.readObject(sid, addr);
          dataType = v.data_type;
          if (dataType) types.current.set(addr, dataType);
        } catch {
          dataType = null;
        }
      }
      let body: ObjectWrite;
      const o = objectAt(addr);
      if (o && entryFor(o, mode) === 'eng') {
        // Typed in engineering units: converted and checked here, the raw value is sent.
        const conv = engineeringToRaw(o, valueText);
        if (!conv.ok) {
          throw new ApiError(`Write ${addr}`, 400, { error: 'ValidationError', message: conv.message, hint: conv.hint ?? undefined });
        }
        body = { value: conv.raw };
        written = `${valueText.trim()} ${o.unit ?? ''}`.trim();
      } else if (isStringType(dataType)) {
        body = { value: valueText };
      } else if (isBytesType(dataType)) {
        const hex = valueText.replace(/[\s_]|0x/gi, '');
        if (!/^([0-9a-f]{2})*$/i.test(hex)) {
          throw new ApiError(`Write ${addr}`, 400, {
            error: 'ValidationError',
            message: `"${valueText}" is not a byte string`,
            hint: 'enter bytes in bus order as hex pairs, e.g. 01 02 0A',
          });
        }
        body = { raw_hex: hex.toLowerCase() };
      } else {
        const parsed = parseNumberInput(valueText, mode, dataType);
        if (!parsed.ok) {
          throw new ApiError(`Write ${addr}`, 400, {
            error: 'ValidationError',
            message: parsed.message,
            hint: mode === 'hex' ? 'digits 0-9 and A-F; switch to Dec for decimal input' : 'switch to Hex for hexadecimal input',
          });
        }
        body = { value: parsed.value };
      }
      const v = await api.writeObject(sid, addr, body);
      show(v);
      record({ op: 'W', address: v.address, result: v, failure: null, written });
    } catch (e) {
      const f = failureOf(e, `Write ${addr}`);
      setResult(null);
      setFailure(f);
      record({ op: 'W', address: addr, result: null, failure: f, written });
    } finally {
      setBusy(null);
    }
  }

  /** Change the base or the entry units, keeping the typed value (converted). */
  function switchTo(m: NumberMode, pref: EntryUnit) {
    const from = entry;
    const to = entryFor(obj, m, pref);
    if (m !== mode) setMode(m);
    if (pref !== entryPref) setEntryPref(pref);
    if (m === mode && from === to) return;
    // A held value is in another unit than this object's: converting it with this object's
    // scale would give a number it never meant. It stays as typed (and is usable again once
    // the entry is its unit).
    if (held !== null) return;
    const addr = parseAddress(address);
    const dt = obj?.data_type ?? (addr.ok ? (types.current.get(formatAddress(addr.address)) ?? null) : null);
    let raw: number | null = null;
    if (from === 'eng' && obj) {
      const p = parseEngineering(valueText);
      raw = p.ok ? toRaw(obj, p.value).raw : null;
    } else {
      const p = parseNumberInput(valueText, mode, dt);
      raw = p.ok ? p.value : null;
    }
    if (raw === null) return;
    setValueText(to === 'eng' && obj ? rawToEngText(raw, obj) : valueToInput(raw, m, dt));
    setTypedIn({ unit: to === 'eng' && obj ? (obj.unit ?? '') : null, address: addressNow });
  }

  function switchMode(m: NumberMode) {
    if (m !== mode) switchTo(m, entryPref);
  }

  function onRead(e: FormEvent) {
    e.preventDefault();
    void read();
  }

  function onWrite(e: FormEvent) {
    e.preventDefault();
    if (blocked) return;
    void write();
  }

  return (
    <div className="objects-grid">
      <div className="stack">
        <section className="card">
          <h2>Access</h2>
          <form className="access-row" onSubmit={onRead}>
            <label>
              Address
              <input
                data-testid="object-address"
                className="mono"
                value={address}
                onChange={(e) => setAddress(e.target.value)}
                placeholder="0x6040:00, 6040h.0, P24640"
                spellCheck={false}
                autoComplete="off"
              />
            </label>
            <button type="submit" className="primary" data-testid="object-read" disabled={busy !== null}>
              {busy === 'read' ? 'Reading…' : 'Read'}
            </button>
          </form>
          <div className="quick">
            {QUICK.map((q) => (
              <button
                type="button"
                key={q.addr}
                className="chip"
                title={q.name}
                onClick={() => {
                  setAddress(q.addr);
                  void read(q.addr);
                }}
              >
                <span className="mono">{q.addr.replace(':00', '')}</span> {q.name}
              </button>
            ))}
          </div>
          <form className="access-row" onSubmit={onWrite}>
            <label>
              <span className="access-value-label" data-testid="object-value-label">
                Value
                {entry === 'eng' && obj ? (
                  <> ({obj.unit})</>
                ) : obj && offersEngineeringEntry(obj) ? (
                  <> (raw{obj.raw_unit ? `, ${obj.raw_unit}` : ''})</>
                ) : null}
              </span>
              <input
                data-testid="object-value"
                className="mono"
                value={valueText}
                onChange={(e) => {
                  setValueText(e.target.value);
                  setTypedIn({ unit: unitNow, address: addressNow });
                }}
                placeholder={entry === 'eng' ? `${obj?.unit ?? ''}, e.g. 1500` : mode === 'hex' ? 'hex, e.g. 3E8' : 'decimal, e.g. 1000'}
                aria-invalid={held !== null || (engCheck !== null && !engCheck.ok)}
                spellCheck={false}
                autoComplete="off"
              />
            </label>
            {obj && offersEngineeringEntry(obj) && (
              <div className="access-entry">
                <span id="object-entry-label">Enter in</span>
                <div className="segmented" role="group" aria-labelledby="object-entry-label">
                  <button type="button" className={entry === 'eng' ? 'on' : ''} aria-pressed={entry === 'eng'} data-testid="object-entry-eng" onClick={() => switchTo('dec', 'eng')}>
                    {obj.unit}
                  </button>
                  <button type="button" className={entry === 'raw' ? 'on' : ''} aria-pressed={entry === 'raw'} data-testid="object-entry-raw" onClick={() => switchTo(mode, 'raw')}>
                    raw{obj.raw_unit ? ` (${obj.raw_unit})` : ''}
                  </button>
                </div>
              </div>
            )}
            <div className="segmented" role="group" aria-label="Number base">
              <button
                type="button"
                className={mode === 'dec' ? 'on' : ''}
                data-testid="value-mode-dec"
                aria-pressed={mode === 'dec'}
                onClick={() => switchMode('dec')}
              >
                Dec
              </button>
              <button
                type="button"
                className={mode === 'hex' ? 'on' : ''}
                data-testid="value-mode-hex"
                aria-pressed={mode === 'hex'}
                onClick={() => switchMode('hex')}
              >
                Hex
              </button>
            </div>
            <button type="submit" className="primary" data-testid="object-write" disabled={busy !== null || blocked !== null} title={blocked ?? undefined}>
              {busy === 'write' ? 'Writing…' : 'Write'}
            </button>
          </form>
          {held !== null && (
            <div className="small warn-text" role="status" data-testid="object-entry-held">
              {held}
            </div>
          )}
          {engCheck &&
            (engCheck.ok ? (
              <div className="small ve-preview" data-testid="object-entry-preview">
                {engCheck.preview}
                {engCheck.note ? <span className="warn-text"> · {engCheck.note}</span> : null}
              </div>
            ) : (
              <div className="inline-error" role="alert" data-testid="object-entry-error">
                {engCheck.message}
                {engCheck.hint ? <span className="ve-hint"> — {engCheck.hint}</span> : null}
              </div>
            ))}
          <ControlNote sid={sid} what="Write is disabled; Read works" rights={{ write: 'write_parameters' }} />
          <div className="muted small">
            Writes are checked against the profile (type, range, access) before they go to the drive, and read back after.
          </div>
        </section>
        <section className="card">
          <h2>Result</h2>
          {failure ? <FailureView f={failure} /> : result ? <ResultView v={result} /> : <div className="muted">Read an object to see it here.</div>}
        </section>
      </div>
      <section className="card">
        <h2>
          History <span className="muted">(last {HISTORY_LENGTH})</span>
        </h2>
        {history.length === 0 ? (
          <div className="muted">No access yet.</div>
        ) : (
          <table className="grid history" data-testid="object-history">
            <thead>
              <tr>
                <th>Time</th>
                <th />
                <th>Address</th>
                <th>Object</th>
                <th className="num">Value</th>
                <th className="num">Hex</th>
              </tr>
            </thead>
            <tbody>
              {history.map((h) => {
                const cells = h.result ? valueCells(h.result) : null;
                return (
                  <tr
                    key={h.id}
                    className={h.failure ? 'row-bad' : ''}
                    data-testid="history-row"
                    onClick={() => setAddress(h.address)}
                    title="click to use this address"
                  >
                    <td className="mono muted">{h.time.toLocaleTimeString([], { hour12: false })}</td>
                    <td className={`mono op op-${h.op}`}>{h.op}</td>
                    <td className="mono">{h.address}</td>
                    <td>{h.result?.name ?? ''}</td>
                    {h.failure ? (
                      <td colSpan={2} className="bad">
                        {h.failure.code_hex ? <span className="mono">{h.failure.code_hex} </span> : null}
                        {h.failure.meaning ?? h.failure.message}
                      </td>
                    ) : (
                      <>
                        <td className="mono num">
                          {cells?.dec}
                          {h.result?.value_text ? <span className="muted"> ({h.result.value_text})</span> : null}
                        </td>
                        <td className="mono num">{cells?.hex}</td>
                      </>
                    )}
                  </tr>
                );
              })}
            </tbody>
          </table>
        )}
      </section>
    </div>
  );
}
