/**
 * Parameters: the "card parameters" page of the LEC-S-NP PROFINET card web server (LECSN
 * manual §20.7), for every drive family. The session profile's configuration parameters
 * (writable, not process values) grouped as the profile groups them (PA, PB, PC, ... on the
 * LECSN), one group at a time; values read in batches for the shown group only; raw value in
 * decimal and hex with its raw unit, the engineering value with its unit, enumeration text;
 * entry in decimal or hex, checked in the browser before it is written, and the read-back.
 *
 * A dirty marker shows what was written since the last save (SessionInfo.dirty: those differ
 * from the drive's non-volatile copy), a second marker what differs from the default. "Save to
 * EEPROM" (POST /store; the LECSN takes up to ~25 s, §20.9.1) shows progress from the
 * WebSocket and the elapsed time. "Restore defaults" asks first. Writing, saving and
 * restoring defaults need control of the drive (docs/api.md "Control and motion as built"):
 * without it the buttons are disabled and a note says why and offers Take control.
 */
import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import { api } from '../api/client';
import type { ObjectInfo, ObjectValue, ObjectWrite, ProfileDetail, StoreResult } from '../api/types';
import { ConfirmDialog } from '../components/ConfirmDialog';
import { ControlNote, useWriteGate } from '../components/ControlNote';
import { FailureBox } from '../components/FailureBox';
import { ProgressBar } from '../components/ProgressBar';
import { ValueEditor } from '../components/ValueEditor';
import { type Failure, codeInObject, failureOf, failureOfBody } from '../lib/codes';
import {
  batches,
  canonicalAddress,
  differsFromDefault,
  formatPnu,
  groupObjects,
  hasPnu,
  hasSymbol,
  isParameter,
  isReadable,
} from '../lib/dictionary';
import type { NumberMode } from '../lib/format';
import { rangeText } from '../lib/validate';
import { decText, engineeringText, enumText, hasEngineering, hexText, isObjectValue } from '../lib/values';
import { useSessionInfo, useSessionProfile } from '../state/profileCache';
import { hashPart, partHref } from '../state/router';
import { watchProgress } from '../ws/progress';
import './dataPages.css';
import type { PageProps } from './registry';

/** Rows per table page: a long group (the LECSN point tables, 1785 entries) is paged. */
const PAGE_ROWS = 200;
/** Addresses per POST /read (the API takes at most 512). */
const READ_BATCH = 256;

type Cell = { v: ObjectValue } | { f: Failure };

interface StoreState {
  running: boolean;
  started: number;
  elapsed: number;
  fraction: number | null;
  message: string | null;
  result: StoreResult | null;
  failure: Failure | null;
}

function procedureText(profile: ProfileDetail, quirk: string, index: number, value: number, word: string): string {
  const q = profile.quirks.find((x) => x.id === quirk);
  const v = q?.value as { index?: number; subindex?: number; value?: number } | undefined;
  if (v && typeof v.index === 'number') {
    const sub = v.subindex ?? 1;
    const val = typeof v.value === 'number' ? `0x${v.value.toString(16).toUpperCase()}` : String(v.value);
    return `${v.index.toString(16).toUpperCase().padStart(4, '0')}h:${sub.toString(16).toUpperCase().padStart(2, '0')} ← ${val}${q?.section ? ` (${q.section})` : ''}`;
  }
  return `${index.toString(16).toUpperCase()}h:01 ← 0x${value.toString(16).toUpperCase()} ("${word}", CiA 301)`;
}

/** The object's name in the profile, for the list of what a save stores. */
function objectName(profile: ProfileDetail, address: string): string {
  const o = profile.object_list.find((x) => canonicalAddress(x.address) === address);
  return o ? o.name : '';
}

export function ParametersPage({ sid }: PageProps) {
  const { info, refresh } = useSessionInfo(sid);
  const { profile, error: profileError } = useSessionProfile(info);

  const params = useMemo(() => (profile ? profile.object_list.filter(isParameter) : []), [profile]);
  const groups = useMemo(() => (profile ? groupObjects(profile, params) : []), [profile, params]);
  const showPnu = useMemo(() => hasPnu(params), [params]);
  const showSymbol = useMemo(() => hasSymbol(params), [params]);
  const errors = profile?.error_list ?? [];

  // A link may name the group to open (#/parameters/<sid>/<group>: Tuning's "What applies
  // instead"); the hash follows the group shown, so it can be bookmarked.
  const [groupId, setGroupId] = useState<string | null>(() => hashPart(window.location.hash));
  useEffect(() => {
    const onHash = () => {
      const g = hashPart(window.location.hash);
      if (g !== null) setGroupId(g);
    };
    window.addEventListener('hashchange', onHash);
    return () => window.removeEventListener('hashchange', onHash);
  }, []);
  const [pageNo, setPageNo] = useState(0);
  const [cells, setCells] = useState<Map<string, Cell>>(new Map());
  const [reading, setReading] = useState<{ done: number; total: number } | null>(null);
  const [mode, setMode] = useState<NumberMode>('dec');
  const [editing, setEditing] = useState<string | null>(null);
  const [store, setStore] = useState<StoreState | null>(null);
  const [restoreOpen, setRestoreOpen] = useState(false);
  /** "Save to EEPROM" lists what it stores before it stores it (issue "Motion safety"). */
  const [storeOpen, setStoreOpen] = useState(false);
  const [restoring, setRestoring] = useState(false);
  const blocked = useWriteGate(sid, { write: 'write_parameters' }).write;
  const [restoreResult, setRestoreResult] = useState<string | null>(null);
  const [restoreFailure, setRestoreFailure] = useState<Failure | null>(null);
  const readToken = useRef(0);

  const group = groups.find((g) => g.group.id === groupId) ?? groups[0] ?? null;
  const rows = group?.objects ?? [];
  const pages = Math.max(1, Math.ceil(rows.length / PAGE_ROWS));
  const page = Math.min(pageNo, pages - 1);
  const shown = useMemo(() => rows.slice(page * PAGE_ROWS, (page + 1) * PAGE_ROWS), [rows, page]);
  const dirty = useMemo(() => new Set((info?.dirty ?? []).map(canonicalAddress)), [info]);
  const showEng = shown.some(hasEngineering);
  const showEnum = shown.some((o) => o.values && Object.keys(o.values).length > 0);
  // The LECSN's servo parameters carry symbols (PA01...); other groups and families do not.
  const showSym = showSymbol && shown.some((o) => !!o.symbol);

  const readShown = useCallback(
    async (objects: readonly ObjectInfo[]) => {
      const token = ++readToken.current;
      const addrs = objects.filter(isReadable).map((o) => o.address);
      setReading({ done: 0, total: addrs.length });
      let done = 0;
      for (const batch of batches(addrs, READ_BATCH)) {
        try {
          const res = await api.readMany(sid, batch);
          if (token !== readToken.current) return;
          setCells((prev) => {
            const next = new Map(prev);
            res.results.forEach((r, i) => {
              const addr = canonicalAddress(r.address ?? batch[i] ?? '');
              if (isObjectValue(r)) next.set(addr, { v: r });
              else if ('error' in r) next.set(addr, { f: failureOfBody(r.error, `Read ${addr}`, errors) });
            });
            return next;
          });
        } catch (e) {
          if (token !== readToken.current) return;
          const f = failureOf(e, `Read ${batch.length} objects`, errors);
          setCells((prev) => {
            const next = new Map(prev);
            for (const a of batch) next.set(a, { f });
            return next;
          });
        }
        done += batch.length;
        setReading({ done, total: addrs.length });
      }
      if (token === readToken.current) setReading(null);
    },
    // `errors` comes from the profile, so the profile stands for it here.
    [sid, profile],
  );

  useEffect(() => {
    if (shown.length) void readShown(shown);
  }, [shown, readShown]);

  // Elapsed time of a running save, ticking while the drive works.
  useEffect(() => {
    if (!store?.running) return;
    const t = setInterval(() => setStore((s) => (s && s.running ? { ...s, elapsed: (performance.now() - s.started) / 1000 } : s)), 100);
    return () => clearInterval(t);
  }, [store?.running]);

  async function save() {
    const started = performance.now();
    setStore({ running: true, started, elapsed: 0, fraction: 0, message: 'starting…', result: null, failure: null });
    const watch = watchProgress(sid, 'store', (m) =>
      setStore((s) => (s && s.running ? { ...s, fraction: m.fraction, message: m.message } : s)),
    );
    await watch.ready;
    try {
      const result = await api.store(sid);
      setStore({ running: false, started, elapsed: (performance.now() - started) / 1000, fraction: 1, message: null, result, failure: null });
    } catch (e) {
      setStore({ running: false, started, elapsed: (performance.now() - started) / 1000, fraction: null, message: null, result: null, failure: failureOf(e, 'Save to EEPROM', errors) });
    } finally {
      watch.close();
      await refresh();
    }
  }

  async function restoreDefaults() {
    setRestoring(true);
    setRestoreFailure(null);
    setRestoreResult(null);
    try {
      const r = await api.restoreDefaults(sid, { confirm: true, reset: true });
      setRestoreResult(r.message);
      setRestoreOpen(false);
      setCells(new Map());
      await refresh();
      // The drive restarts after the NMT reset; give it a moment before reading the group.
      await new Promise((res) => setTimeout(res, 400));
      await readShown(shown);
    } catch (e) {
      setRestoreFailure(failureOf(e, 'Restore defaults', errors));
      setRestoreOpen(false);
    } finally {
      setRestoring(false);
    }
  }

  async function writeOne(o: ObjectInfo, body: ObjectWrite): Promise<ObjectValue> {
    const v = await api.writeObject(sid, o.address, body);
    setCells((prev) => new Map(prev).set(o.address, { v }));
    void refresh();
    return v;
  }

  if (profileError) {
    return <FailureBox f={failureOf(profileError, 'Load the profile')} />;
  }
  if (!info || !profile) return <div className="muted">Loading the profile…</div>;

  const dirtyIn = (objs: readonly ObjectInfo[]) => objs.reduce((n, o) => n + (dirty.has(o.address) ? 1 : 0), 0);
  const storeProc = procedureText(profile, 'store_parameters', 0x1010, 0x65766173, 'save');
  const restoreProc = procedureText(profile, 'restore_defaults', 0x1011, 0x64616f6c, 'load');
  const colCount = 9 + (showPnu ? 1 : 0) + (showSym ? 1 : 0) + (showEng ? 1 : 0) + (showEnum ? 1 : 0);

  return (
    <div className="stack params-page">
      <section className="card">
        <h2>
          {profile.name}
          <span className="h2-side muted">
            {params.length} parameters in {groups.length} groups · profile {profile.id}
          </span>
        </h2>
        <div className="params-toolbar">
          <div className={`dirty-summary${dirty.size ? ' has-dirty' : ''}`} data-testid="params-dirty-count">
            {dirty.size ? (
              <>
                <span className="dirty-dot">●</span> {dirty.size} written since the last save (not yet in the drive’s non-volatile memory)
              </>
            ) : (
              'Nothing written since the last save'
            )}
          </div>
          <div className="toolbar-actions">
            <span className="small muted">Entry</span>
            <div className="segmented" role="group" aria-label="Entry base">
              <button type="button" className={mode === 'dec' ? 'on' : ''} aria-pressed={mode === 'dec'} data-testid="params-mode-dec" onClick={() => setMode('dec')}>
                Dec
              </button>
              <button type="button" className={mode === 'hex' ? 'on' : ''} aria-pressed={mode === 'hex'} data-testid="params-mode-hex" onClick={() => setMode('hex')}>
                Hex
              </button>
            </div>
            <button type="button" onClick={() => void readShown(shown)} disabled={reading !== null} data-testid="params-reload">
              {reading ? `Reading ${reading.done}/${reading.total}…` : 'Read group'}
            </button>
            <button
              type="button"
              className="primary"
              onClick={() => setStoreOpen(true)}
              disabled={store?.running === true || blocked !== null}
              data-testid="params-store"
              title={blocked ?? `Store the drive's parameters in non-volatile memory: ${storeProc}`}
            >
              {store?.running ? 'Saving…' : 'Save to EEPROM…'}
            </button>
            <button
              type="button"
              className="warn-outline"
              onClick={() => setRestoreOpen(true)}
              disabled={restoring || blocked !== null}
              title={blocked ?? undefined}
              data-testid="params-restore"
            >
              Restore defaults…
            </button>
          </div>
        </div>
        <ControlNote sid={sid} what="Write, Save to EEPROM and Restore defaults are disabled; reading works" rights={{ write: 'write_parameters' }} />
        {store && (
          <div className="store-status" data-testid="params-store-status">
            {store.running ? (
              <>
                <ProgressBar
                  fraction={store.fraction}
                  testid="params-store-progress"
                  label={`${store.message ?? 'saving…'} · ${store.elapsed.toFixed(1)} s elapsed`}
                />
                <div className="warn-text small">Do not switch the drive off while it saves.</div>
              </>
            ) : store.result ? (
              <div className="ok-line" data-testid="params-store-result">
                <span className="ok-mark">✓</span> Saved to non-volatile memory: {store.result.stored} changed parameter
                {store.result.stored === 1 ? '' : 's'} in {store.result.duration_s.toFixed(1)} s{' '}
                <span className="muted mono">({store.result.procedure})</span>
              </div>
            ) : store.failure ? (
              <FailureBox f={store.failure} testid="store-failure" />
            ) : null}
          </div>
        )}
        {restoreResult && (
          <div className="ok-line" data-testid="params-restore-result">
            <span className="ok-mark">✓</span> {restoreResult}
          </div>
        )}
        {restoreFailure && <FailureBox f={restoreFailure} testid="restore-failure" />}
      </section>

      <div className="params-body">
        <nav className="group-list" aria-label="Parameter groups" data-testid="params-groups">
          {groups.map((g) => {
            const nd = dirtyIn(g.objects);
            const active = g.group.id === group?.group.id;
            return (
              <button
                type="button"
                key={g.group.id || '_other'}
                className={`group-item${active ? ' active' : ''}`}
                data-testid={`group-tab-${g.group.id || 'other'}`}
                aria-current={active ? 'true' : undefined}
                title={[g.group.name_local, g.group.description].filter(Boolean).join(' · ')}
                onClick={() => {
                  setGroupId(g.group.id);
                  window.history.replaceState(null, '', partHref('parameters', sid, g.group.id));
                  setPageNo(0);
                  setEditing(null);
                }}
              >
                <span className="group-name">{g.group.name}</span>
                <span className="group-count muted">{g.objects.length}</span>
                {nd > 0 && (
                  <span className="group-dirty" title={`${nd} written since the last save`}>
                    ● {nd}
                  </span>
                )}
              </button>
            );
          })}
        </nav>

        <section className="card params-table-card">
          {group && (
            <h2>
              {group.group.name}
              {group.group.name_local ? <span className="muted local-name">{group.group.name_local}</span> : null}
              <span className="h2-side muted">
                {group.group.description ? `${group.group.description} · ` : ''}
                {rows.length} parameters
              </span>
            </h2>
          )}
          {pages > 1 && (
            <div className="pager" data-testid="params-pager">
              <button type="button" disabled={page === 0} onClick={() => setPageNo(page - 1)}>
                ‹ Previous
              </button>
              <span className="small">
                Rows {page * PAGE_ROWS + 1}–{Math.min(rows.length, (page + 1) * PAGE_ROWS)} of {rows.length}
              </span>
              <button type="button" disabled={page >= pages - 1} onClick={() => setPageNo(page + 1)}>
                Next ›
              </button>
            </div>
          )}
          {reading && reading.total > 0 && (
            <ProgressBar fraction={reading.done / reading.total} label={`Reading ${reading.done} of ${reading.total} values…`} testid="params-read-progress" />
          )}
          <table className="grid params-table" data-testid="params-table" data-group={group?.group.id ?? ''}>
            <thead>
              <tr>
                <th className="marker-col" title="● written since the last save · ≠ differs from the default" />
                {showPnu && <th title="PROFIdrive parameter number (LECSN manual §20.1.5)">PNU</th>}
                {showSym && <th>Symbol</th>}
                <th>Index</th>
                <th>Name</th>
                <th className="num" title="The value as the drive holds it, in its raw unit">
                  Raw value (dec)
                </th>
                <th>Raw unit</th>
                <th className="num">Hex</th>
                {showEng && (
                  <th className="num" title="Raw value × scale, in engineering units">
                    Engineering
                  </th>
                )}
                {showEnum && <th>Meaning</th>}
                <th className="num">Default</th>
                <th>Range (raw)</th>
                <th />
              </tr>
            </thead>
            <tbody>
              {shown.map((o) => {
                const cell = cells.get(o.address);
                const v = cell && 'v' in cell ? cell.v : null;
                const f = cell && 'f' in cell ? cell.f : null;
                const isDirty = dirty.has(o.address);
                const differs = differsFromDefault(o, v?.value);
                const eng = v ? engineeringText(v, o, v.value) : null;
                const et = v ? (v.value_text ?? enumText(o, v.value)) : null;
                const code = v ? codeInObject(o, v.value, errors) : null;
                const isEditing = editing === o.address;
                return [
                  <tr
                    key={o.address}
                    className={`${isDirty ? 'row-dirty' : ''}${isEditing ? ' row-editing' : ''}`}
                    data-testid={`param-row-${o.address}`}
                    data-dirty={isDirty ? '1' : '0'}
                    data-differs={differs === null ? '' : differs ? '1' : '0'}
                  >
                    <td className="marker-col">
                      {isDirty && (
                        <span className="dirty-dot" data-testid="dirty-marker" title="Written since the last save: differs from the drive's non-volatile copy. Save to EEPROM to keep it.">
                          ●
                        </span>
                      )}
                      {differs && (
                        <span className="differs-mark" data-testid="differs-marker" title={`Differs from the default ${decText(o.default)}`}>
                          ≠
                        </span>
                      )}
                    </td>
                    {showPnu && <td className="mono nowrap">{formatPnu(o)}</td>}
                    {showSym && <td className="mono nowrap sym">{o.symbol ?? ''}</td>}
                    <td className="mono nowrap">{o.address}</td>
                    <td className="name-cell" title={[o.name_local, o.data_type, o.description].filter(Boolean).join('\n')}>
                      {o.name}
                    </td>
                    {f ? (
                      <td colSpan={3 + (showEng ? 1 : 0) + (showEnum ? 1 : 0)} className="bad small read-error" title={[f.message, f.hint].filter(Boolean).join('\n')}>
                        {f.code_hex ? <span className="mono">{f.code_hex} </span> : null}
                        {f.meaning ?? f.message}
                      </td>
                    ) : (
                      <>
                        <td className="mono num nowrap" data-testid="param-value">
                          {v ? decText(v.value) : isReadable(o) ? '…' : <span className="muted">write-only</span>}
                        </td>
                        <td className="raw-unit">{v?.raw_unit ?? o.raw_unit ?? ''}</td>
                        <td className="mono num nowrap muted">{v ? hexText(v.value, o.data_type) : ''}</td>
                        {showEng && <td className="mono num nowrap">{eng ?? ''}</td>}
                        {showEnum && (
                          <td className="small" title={code?.cause ?? ''}>
                            {et ?? (code ? `${code.display ?? code.code_hex} ${code.name}` : '')}
                          </td>
                        )}
                      </>
                    )}
                    <td className="mono num nowrap muted">{decText(o.default)}</td>
                    <td className="mono small nowrap muted" title={rangeText(o, 'dec', true) ? '' : `no profile limits; type range ${rangeText(o)}`}>
                      {rangeText(o, 'dec', true, false) || '—'}
                    </td>
                    <td className="actions">
                      <button type="button" className="small-btn" data-testid={`edit-${o.address}`} onClick={() => setEditing(isEditing ? null : o.address)}>
                        {isEditing ? 'Close' : 'Edit'}
                      </button>
                    </td>
                  </tr>,
                  isEditing ? (
                    <tr key={`${o.address}-edit`} className="edit-row" data-testid={`param-edit-${o.address}`}>
                      <td colSpan={colCount}>
                        {code && (
                          <div className="small code-line">
                            Code {code.display ?? code.code_hex}: {code.name}
                            {code.remedy ? ` — ${code.remedy}` : ''}
                          </div>
                        )}
                        {o.description && <div className="small muted param-desc">{o.description}</div>}
                        <ValueEditor
                          key={o.address}
                          obj={o}
                          current={v?.value}
                          mode={mode}
                          onMode={setMode}
                          errors={errors}
                          autoFocus
                          write={(body) => writeOne(o, body)}
                          blocked={blocked}
                          onCancel={() => setEditing(null)}
                        />
                      </td>
                    </tr>
                  ) : null,
                ];
              })}
            </tbody>
          </table>
          <div className="small muted legend">
            <span className="dirty-dot">●</span> written since the last save (differs from the non-volatile copy) ·{' '}
            <span className="differs-mark">≠</span> differs from the default · Raw value in the drive’s own unit; Engineering = raw × scale in
            the unit named · Save with <em>Save to EEPROM</em> ({storeProc}).
          </div>
        </section>
      </div>

      {storeOpen && (
        <ConfirmDialog
          title="Save to EEPROM?"
          confirmLabel="Save"
          busy={store?.running === true}
          onCancel={() => setStoreOpen(false)}
          onConfirm={() => {
            setStoreOpen(false);
            void save();
          }}
          testid="store-dialog"
        >
          <p>
            This tells <strong>{info.profile_name}</strong> (node {info.node_id}) to store the parameters it holds now in its
            non-volatile memory: <span className="mono">{storeProc}</span>.
          </p>
          {dirty.size > 0 ? (
            <>
              <p>Written through servodesk since the last save ({dirty.size}):</p>
              <ul className="mono small" data-testid="store-dirty-list">
                {[...dirty].sort().map((a) => (
                  <li key={a} data-testid={`store-dirty-${a}`}>
                    {a} {objectName(profile, a)}
                  </li>
                ))}
              </ul>
            </>
          ) : (
            <p data-testid="store-dirty-none">Nothing was written through servodesk since the last save.</p>
          )}
          <p className="muted small">
            Settings a jog, move or homing run needed are put back when it ends and are not in this list. The drive stores
            everything it holds, also what other tools changed.
          </p>
        </ConfirmDialog>
      )}
      {restoreOpen && (
        <ConfirmDialog
          title="Restore factory defaults?"
          confirmLabel="Restore defaults and reset the drive"
          busy={restoring}
          onCancel={() => setRestoreOpen(false)}
          onConfirm={() => void restoreDefaults()}
          testid="restore-dialog"
        >
          <p>
            This tells <strong>{info.profile_name}</strong> (node {info.node_id}) to replace <strong>all</strong> its parameters with the
            factory defaults: <span className="mono">{restoreProc}</span>. Then servodesk resets the drive (NMT reset node) so the defaults
            take effect at once.
          </p>
          <ul>
            <li>Every parameter set during commissioning is lost, saved or not{dirty.size ? ` (including the ${dirty.size} not yet saved)` : ''}.</li>
            <li>The drive restarts: communication stops for a moment and the axis is disabled. Make sure it is at standstill.</li>
            <li>Back the parameters up first (Backup &amp; restore) if you may need them again.</li>
          </ul>
        </ConfirmDialog>
      )}
    </div>
  );
}
