/**
 * PDO mapping (issue 6 item 7, docs/pdo.md): the drive's process data layout as tables with
 * byte and bit offsets and a bit budget per PDO, edited by dragging objects from the palette
 * (or with the keyboard), checked live against the family's rules by the server, planned,
 * confirmed and applied with progress and a report; templates, exports for the PLC
 * programmer, and the cyclic data with live values next to each mapped object.
 *
 * The family decides what can be edited (`PdoView.kind`): CANopen PDOs with their
 * communication parameters (CiA 301 §7.5.2.35-38), EtherCAT mapping objects with the sync
 * manager assignment 1C12h/1C13h (HIWIN 000 §2.8.2), the LECSN's telegram filled to its size
 * with Reserved entries (004 §20.1.2), or a fixed mapping shown read-only (CTMM04x, 003 §4-1).
 */
import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import { PdoRefusedError, pdoApi } from '../api/pdo';
import type {
  PdoApplyReport,
  PdoDirection,
  PdoExportFormat,
  PdoKind,
  PdoMappable,
  PdoProblem,
  PdoTelegramInfo,
  PdoTemplate,
  PdoView,
} from '../api/types';
import { saveBlob } from '../components/pdo/download';
import { ApplyPanel } from '../components/pdo/ApplyPanel';
import { CyclicPanel } from '../components/pdo/CyclicPanel';
import { BudgetBar, ProblemList } from '../components/pdo/fields';
import { Palette } from '../components/pdo/Palette';
import { type DragState, PdoCard } from '../components/pdo/PdoCard';
import { EMPTY_LIVE, type PdoLive, watchPdoLive } from '../components/pdo/pdoLive';
import {
  DIRECTIONS,
  type Draft,
  type DragItem,
  addEntry,
  applyDrop,
  canDrop,
  changedPdos,
  describeFrom,
  directionBudget,
  draftChanged,
  draftFromView,
  groupProblems,
  hex,
  isActive,
  layoutFromDraft,
  moveItem,
  pdoKey,
  removeEntry,
  setComm,
  telegramBudget,
} from '../components/pdo/pdoModel';
import '../components/pdo/pdo.css';
import { FailureBox } from '../components/FailureBox';
import { type Failure, failureOf } from '../lib/codes';
import { Observable } from '../state/observable';
import { hasNmt, nmtTitle } from '../lib/nmt';
import { useSessionInfo, useSessionProfile } from '../state/profileCache';
import type { PageProps } from './registry';
import './dataPages.css';

/** Debounce of the live check (docs/pdo.md POST /pdo/validate). */
const VALIDATE_DELAY_MS = 250;

const EXPORTS: Record<PdoKind, PdoExportFormat[]> = {
  canopen: ['csv', 'dcf', 'json'],
  ethercat: ['csv', 'esi', 'json'],
  fixed: ['csv', 'json'],
  telegram: ['csv', 'json'],
};

const EXPORT_TITLES: Record<PdoExportFormat, string> = {
  csv: 'Byte offsets and types per PDO, for the PLC programmer',
  dcf: 'Device configuration file (CiA 306) with this mapping',
  esi: 'EtherCAT ESI fragment (RxPdo/TxPdo) with this mapping',
  json: 'The mapping as servodesk reads it (servodesk pdo apply FILE)',
};

const KIND_TEXT: Record<PdoKind, string> = {
  canopen: 'CANopen PDOs (CiA 301)',
  ethercat: 'EtherCAT PDO mapping and sync manager assignment',
  fixed: 'Fixed mapping',
  telegram: 'PROFIdrive telegram',
};

/** A telegram choice's label from the profile's telegram (004 §20.3); the server checks the
 * mapping. */
function telegramLabel(t: PdoTelegramInfo | undefined, n: number): string {
  if (!t) return String(n);
  return t.variable
    ? `${n} · ${t.name}, variable, at most ${t.bytes} bytes / ${t.max_entries} entries`
    : `${n} · ${t.name} (fixed)`;
}

interface Check {
  state: 'idle' | 'checking' | 'done' | 'failed';
  problems: PdoProblem[];
  view: PdoView | null;
  failure: Failure | null;
}

function dirName(kind: PdoKind, d: PdoDirection): string {
  if (kind === 'telegram') return d === 'rx' ? 'Setpoint telegram' : 'Actual-value telegram';
  if (kind === 'ethercat') return d === 'rx' ? 'RxPDO (SM2, 1C12h)' : 'TxPDO (SM3, 1C13h)';
  return d === 'rx' ? 'RX (RPDO)' : 'TX (TPDO)';
}

export function PdoPage({ sid }: PageProps) {
  const { info } = useSessionInfo(sid);
  const { profile } = useSessionProfile(info);
  const errors = useMemo(() => profile?.error_list ?? [], [profile]);
  const rawUnits = useMemo(() => {
    const m = new Map<string, string>();
    for (const o of profile?.object_list ?? []) if (o.raw_unit) m.set(o.address.toUpperCase(), o.raw_unit);
    return m;
  }, [profile]);

  const [view, setView] = useState<PdoView | null>(null);
  const [base, setBase] = useState<Draft | null>(null);
  const [draft, setDraft] = useState<Draft | null>(null);
  const [loadFailure, setLoadFailure] = useState<Failure | null>(null);
  const [loading, setLoading] = useState(false);
  const [mappable, setMappable] = useState<PdoMappable | null>(null);
  const [templates, setTemplates] = useState<PdoTemplate[] | null>(null);
  const [sideFailure, setSideFailure] = useState<Failure | null>(null);
  const [templateNote, setTemplateNote] = useState<string | null>(null);
  const [templateView, setTemplateView] = useState<PdoView | null>(null);
  const [check, setCheck] = useState<Check>({ state: 'idle', problems: [], view: null, failure: null });
  const [exportFailure, setExportFailure] = useState<Failure | null>(null);
  const [dragging, setDragging] = useState<DragItem | null>(null);
  const dragTimer = useRef<ReturnType<typeof setTimeout> | null>(null);
  const beginDrag = useCallback((item: DragItem) => {
    if (dragTimer.current) clearTimeout(dragTimer.current);
    // After the browser has started the drag: a re-render inside dragstart can make Chromium
    // end the drag at once. Until then dragover goes by the DataTransfer's types.
    dragTimer.current = setTimeout(() => {
      dragTimer.current = null;
      setDragging(item);
    }, 0);
  }, []);
  const endDrag = useCallback(() => {
    if (dragTimer.current) clearTimeout(dragTimer.current);
    dragTimer.current = null;
    setDragging(null);
  }, []);
  const drag: DragState = useMemo(() => ({ dragging, begin: beginDrag, end: endDrag }), [dragging, beginDrag, endDrag]);
  const [live, setLive] = useState<Observable<PdoLive>>(() => new Observable(EMPTY_LIVE));
  const checkSeq = useRef(0);

  const load = useCallback(async () => {
    setLoading(true);
    try {
      const v = await pdoApi.view(sid);
      const d = draftFromView(v);
      setView(v);
      setBase(d);
      setDraft(d);
      setTemplateNote(null);
      setCheck({ state: 'idle', problems: v.problems, view: v, failure: null });
      setLoadFailure(null);
    } catch (e) {
      setLoadFailure(failureOf(e, 'Read the PDO configuration', errors));
    } finally {
      setLoading(false);
    }
  }, [sid, errors]);

  useEffect(() => {
    void load();
    // Load once per session; `errors` only adds detail to a failure.
  }, [sid]);

  useEffect(() => {
    let live = true;
    Promise.all([pdoApi.mappable(sid), pdoApi.templates(sid)]).then(
      ([m, t]) => {
        if (!live) return;
        setMappable(m);
        setTemplates(t);
      },
      (e: unknown) => live && setSideFailure(failureOf(e, 'Load the mappable objects and templates')),
    );
    return () => {
      live = false;
    };
  }, [sid]);

  useEffect(() => {
    const w = watchPdoLive(sid);
    setLive(w.live);
    return w.stop;
  }, [sid]);

  const kind: PdoKind = view?.kind ?? 'canopen';
  const readOnly = kind === 'fixed' || view?.rules.mapping_state === 'fixed';
  const telegrams = view?.rules.telegrams ?? [];
  // A fixed telegram's layout is the telegram (004 §20.3: 1 and 100): its entries stay as they
  // are; choosing a variable telegram makes them editable.
  const fixedTelegram = kind === 'telegram' && telegrams.find((t) => t.number === draft?.telegram)?.variable === false;
  const layout = useMemo(() => (draft ? layoutFromDraft(draft) : null), [draft]);
  const layoutKey = layout ? JSON.stringify(layout) : '';

  // Live check: every edit is validated by the server after a short pause; only the answer to
  // the latest edit counts.
  useEffect(() => {
    if (!layout || !view || readOnly) return;
    const my = ++checkSeq.current;
    setCheck((c) => ({ ...c, state: 'checking' }));
    const t = setTimeout(() => {
      pdoApi.validate(sid, layout).then(
        (r) => {
          if (my === checkSeq.current) setCheck({ state: 'done', problems: r.problems, view: r.view, failure: null });
        },
        (e: unknown) => {
          if (my !== checkSeq.current) return;
          if (e instanceof PdoRefusedError) setCheck((c) => ({ state: 'done', problems: e.problems, view: c.view, failure: null }));
          else setCheck((c) => ({ ...c, state: 'failed', failure: failureOf(e, 'Check the mapping', errors) }));
        },
      );
    }, VALIDATE_DELAY_MS);
    return () => clearTimeout(t);
  }, [layoutKey, view, readOnly]);

  const edit = (fn: (d: Draft) => Draft) => setDraft((d) => (d ? fn(d) : d));

  const pdoNames = useMemo(() => new Set(draft?.pdos.map((p) => p.name) ?? []), [draft]);
  const grouped = useMemo(() => groupProblems(check.problems, pdoNames), [check.problems, pdoNames]);
  const describe = useMemo(
    () => describeFrom([...(mappable?.rx ?? []), ...(mappable?.tx ?? [])], [view, check.view, templateView]),
    [mappable, view, check.view, templateView],
  );
  const changed = useMemo(() => (draft ? changedPdos(draft, base) : new Set<string>()), [draft, base]);
  const dirty = draft ? draftChanged(draft, base) : false;

  async function loadTemplate(t: PdoTemplate) {
    try {
      const v = await pdoApi.template(sid, t.id, t.name);
      setTemplateView(v);
      setDraft(draftFromView(v));
      setTemplateNote(`Template "${t.name}" loaded into the editor${t.section ? ` (${t.section})` : ''}: review it, then apply. Nothing is written yet.`);
      setSideFailure(null);
    } catch (e) {
      setSideFailure(failureOf(e, `Load template ${t.name}`, errors));
    }
  }

  async function doExport(format: PdoExportFormat) {
    setExportFailure(null);
    try {
      const f = await pdoApi.export(sid, format);
      const ext = format === 'esi' ? 'xml' : format;
      saveBlob(f.blob, f.filename ?? `${sid}-pdo.${ext}`);
    } catch (e) {
      setExportFailure(failureOf(e, `Export the mapping as ${format.toUpperCase()}`, errors));
    }
  }

  function applied(r: PdoApplyReport) {
    if (r.dry_run) return;
    if (!r.view) {
      // The drive could not be read after the run: read it again rather than guess.
      void load();
      return;
    }
    // The report's view is the drive after the run (the new mapping, or the old one put back).
    const d = draftFromView(r.view);
    setView(r.view);
    setBase(d);
    if (r.ok) {
      setDraft(d);
      setTemplateNote(null);
    }
  }

  if (loadFailure && !view) {
    return (
      <div className="stack" data-testid="pdo-page">
        <FailureBox f={loadFailure} testid="pdo-load-failure" />
        <div>
          <button type="button" onClick={() => void load()} data-testid="pdo-reload">
            Try again
          </button>
        </div>
      </div>
    );
  }
  if (!view || !draft || !layout) return <div className="muted" data-testid="pdo-page">Reading the PDO configuration…</div>;

  const maxBitsOf = (direction: PdoDirection, number: number) => {
    const fromCheck = check.view?.pdos.find((p) => p.direction === direction && p.number === number)?.max_bits;
    const fromView = view.pdos.find((p) => p.direction === direction && p.number === number)?.max_bits;
    return fromCheck ?? fromView ?? view.rules.max_bits;
  };

  let blocked: string | null = null;
  if (view.apply_unavailable) blocked = `Not written from here: ${view.apply_unavailable}.`;
  else if (readOnly) blocked = `This family's mapping is fixed and cannot be written${view.rules.section ? ` (${view.rules.section})` : ''}.`;
  else if (!dirty) blocked = 'Nothing to apply: the editor shows what the drive has.';
  else if (check.state === 'checking' || check.state === 'idle') blocked = 'Checking the mapping…';
  else if (check.state === 'failed') blocked = 'The mapping could not be checked.';
  else if (check.problems.length) blocked = `${check.problems.length} problem${check.problems.length === 1 ? '' : 's'} to fix first (shown next to the PDO they name).`;

  const padding = kind === 'telegram';
  const assignmentChoice = (d: PdoDirection) => {
    const assigned = draft.assignment?.[d] ?? [];
    const options = draft.pdos.filter((p) => p.direction === d);
    const obj = d === 'rx' ? '1C12h' : '1C13h';
    return (
      <label key={d}>
        <span>
          {obj} {d === 'rx' ? 'SM2 (outputs)' : 'SM3 (inputs)'}
        </span>
        <select
          value={assigned[0] ?? ''}
          disabled={readOnly}
          onChange={(e) =>
            edit((x) => ({
              ...x,
              assignment: { rx: x.assignment?.rx ?? [], tx: x.assignment?.tx ?? [], [d]: e.target.value ? [Number(e.target.value)] : [] },
            }))
          }
          data-testid={`pdo-assignment-${d}`}
        >
          <option value="">none (no {d === 'rx' ? 'outputs' : 'inputs'})</option>
          {options.map((p) => (
            <option key={p.mapping_index} value={p.mapping_index}>
              {hex(p.mapping_index)} · {p.name}
            </option>
          ))}
        </select>
        {assigned.length > 1 && <span className="muted small">also assigned: {assigned.slice(1).map((i) => hex(i)).join(', ')}</span>}
      </label>
    );
  };

  return (
    <div className="stack" data-testid="pdo-page" data-kind={kind}>
      <section className="card" data-testid="pdo-summary">
        <h2>
          {KIND_TEXT[kind]}
          <span className="h2-side small muted">
            {view.rules.section ?? ''}
            {view.nmt_state && hasNmt(info?.link) ? (
              <span title={nmtTitle(view.nmt_state, info?.link)} data-testid="pdo-nmt">{` · NMT ${view.nmt_state}`}</span>
            ) : (
              ''
            )}{' '}
            · {view.byte_order === 'big' ? 'big-endian' : 'little-endian'}
          </span>
        </h2>
        {readOnly && (
          <div className="bk-warn" data-testid="pdo-readonly">
            Read-only: this family's process data mapping is pre-assigned and is never written by servodesk
            {view.rules.section ? ` (${view.rules.section})` : ''}. It can be exported and its cyclic data shown.
          </div>
        )}
        <div className="bk-row pdo-toolbar">
          {!readOnly && (
            <label className="pdo-inline small muted">
              Template
              <select
                value=""
                onChange={(e) => {
                  const t = templates?.find((x) => x.id === e.target.value);
                  if (t) void loadTemplate(t);
                }}
                disabled={!templates?.length}
                data-testid="pdo-template"
              >
                <option value="">{templates ? (templates.length ? 'Load a template…' : 'no templates') : 'loading…'}</option>
                {templates?.map((t) => (
                  <option key={t.id} value={t.id} title={t.description ?? undefined}>
                    {t.name}
                  </option>
                ))}
              </select>
            </label>
          )}
          {!readOnly && (
            <button type="button" disabled={!dirty} onClick={() => base && (setDraft(base), setTemplateNote(null))} data-testid="pdo-revert">
              Revert edits
            </button>
          )}
          <button type="button" disabled={loading} onClick={() => void load()} data-testid="pdo-reload" title="read the mapping from the drive again (drops the edits)">
            {loading ? 'Reading…' : 'Read from drive'}
          </button>
          <span className="spacer" />
          <span className="small muted">Export:</span>
          {EXPORTS[kind].map((f) => (
            <button key={f} type="button" className="small-btn" onClick={() => void doExport(f)} title={EXPORT_TITLES[f]} data-testid={`pdo-export-${f}`}>
              {f.toUpperCase()}
            </button>
          ))}
        </div>
        {loadFailure && <FailureBox f={loadFailure} testid="pdo-load-failure" />}
        {sideFailure && <FailureBox f={sideFailure} testid="pdo-side-failure" />}
        {exportFailure && <FailureBox f={exportFailure} testid="pdo-export-failure" />}
        {templateNote && (
          <div className="bk-warn" data-testid="pdo-template-note">
            {templateNote}
          </div>
        )}
        {!readOnly && (
          <div className="small pdo-check-state" data-testid="pdo-check" data-state={check.state} data-problems={check.problems.length}>
            {check.state === 'checking' && <span className="muted">Checking…</span>}
            {check.state === 'done' && check.problems.length === 0 && <span className="pdo-ok-text">The mapping is valid for this drive.</span>}
            {check.state === 'done' && check.problems.length > 0 && (
              <span className="pdo-over-text">
                {check.problems.length} problem{check.problems.length === 1 ? '' : 's'}
              </span>
            )}
            {dirty && (
              <span className="muted">
                {' '}
                · edited:{' '}
                {[...changed, ...(draft.telegram !== base?.telegram ? ['telegram'] : []), ...(changed.size === 0 && kind === 'ethercat' ? ['sync manager assignment'] : [])].join(', ')}
              </span>
            )}
          </div>
        )}
        {check.failure && <FailureBox f={check.failure} testid="pdo-check-failure" />}
        <ProblemList problems={grouped.general} testid="pdo-general-problems" />
        {kind === 'ethercat' && (
          <div className="pdo-comm" data-testid="pdo-assignment">
            {DIRECTIONS.map(assignmentChoice)}
            <span className="muted small">HIWIN 000 §2.8.2: one mapping object per sync manager; written in PreOp.</span>
          </div>
        )}
        {kind === 'telegram' && (
          <div className="pdo-comm" data-testid="pdo-telegram">
            <label>
              <span>Telegram (P922)</span>
              <select
                value={draft.telegram ?? ''}
                disabled={readOnly}
                onChange={(e) => edit((x) => ({ ...x, telegram: Number(e.target.value) }))}
                data-testid="pdo-telegram-select"
              >
                {[...new Set([...(draft.telegram !== null ? [draft.telegram] : []), ...telegrams.filter((t) => t.variable).map((t) => t.number)])].map((t) => (
                  <option key={t} value={t}>
                    {telegramLabel(telegrams.find((x) => x.number === t), t)}
                  </option>
                ))}
              </select>
            </label>
            {draft.pdos.map((p) => {
              const tb = telegramBudget(draft.telegram ?? 0, maxBitsOf(p.direction, p.number), p.entries);
              return (
                <div key={p.name} className="pdo-telegram-budget">
                  <BudgetBar
                    used={tb.bytes}
                    max={tb.size}
                    over={tb.missing < 0}
                    testid={`pdo-telegram-budget-${p.direction}`}
                    label={
                      <>
                        {p.name}:{' '}
                        <span className="mono">
                          {tb.bytes} / {tb.size} bytes
                        </span>
                        {tb.missing > 0 && <span className="pdo-warn-text"> · fill {tb.missing} bytes with Reserved entries</span>}
                        {tb.missing < 0 && <span className="pdo-over-text"> · {-tb.missing} bytes too long</span>}
                        {tb.missing === 0 && <span className="pdo-ok-text"> · exactly the telegram's size</span>}
                      </>
                    }
                  />
                </div>
              );
            })}
          </div>
        )}
        {view.rules.max_bytes !== null && view.rules.max_bytes !== undefined && (
          <div className="pdo-dir-budgets">
            {DIRECTIONS.map((d) => {
              const b = directionBudget(draft, d, kind, view.rules.max_bytes);
              return (
                <BudgetBar
                  key={d}
                  used={b.bytes}
                  max={b.maxBytes ?? 0}
                  over={b.over}
                  testid={`pdo-dir-budget-${d}`}
                  label={
                    <>
                      {dirName(kind, d)}:{' '}
                      <span className="mono">
                        {b.bytes} / {b.maxBytes} bytes
                      </span>{' '}
                      <span className="muted">({b.pdos.join(', ') || 'none on the bus'})</span>
                    </>
                  }
                />
              );
            })}
          </div>
        )}
      </section>

      <div className="pdo-two">
        <ApplyPanel
          sid={sid}
          layout={layout}
          blocked={blocked}
          errors={errors}
          onRefused={(problems) => setCheck((c) => ({ ...c, state: 'done', problems }))}
          onApplied={applied}
        />
        <CyclicPanel
          sid={sid}
          live={live}
          errors={errors}
          onApplied={applied}
          driveTelegram={view?.telegram ?? null}
          onStarted={(st) => {
            // The IO AR set the drive up with another telegram (P922 follows): show its layout.
            if (st.telegram != null && st.telegram !== view?.telegram) void load();
          }}
        />
      </div>

      <div className="pdo-layout">
        <div className="stack pdo-tables" data-testid="pdo-tables">
          {DIRECTIONS.map((d) => {
            const pdos = draft.pdos.filter((p) => p.direction === d);
            if (!pdos.length) return null;
            return (
              <div key={d} className="stack" data-testid={`pdo-direction-${d}`}>
                <h3 className="pdo-dir-title">{dirName(kind, d)}</h3>
                {pdos.map((p) => {
                  const key = pdoKey(p);
                  return (
                    <PdoCard
                      key={key}
                      pdo={p}
                      kind={kind}
                      maxBits={maxBitsOf(p.direction, p.number)}
                      maxEntries={view.rules.max_entries}
                      active={isActive(p, draft, kind)}
                      changed={changed.has(p.name)}
                      readOnly={readOnly || fixedTelegram}
                      problems={grouped.byPdo.get(p.name)}
                      describe={describe}
                      rawUnits={rawUnits}
                      mappable={mappable?.[p.direction] ?? []}
                      padding={padding}
                      slots={(check.view ?? view)?.pdos.find((q) => q.direction === p.direction && q.number === p.number)?.entries}
                      live={live}
                      drag={drag}
                      canDropHere={(item) => canDrop(draft, item, p)}
                      onDrop={(item, target) => edit((x) => applyDrop(x, item, target))}
                      onAdd={(entry) => edit((x) => addEntry(x, key, entry))}
                      onRemove={(at) => edit((x) => removeEntry(x, key, at))}
                      onMove={(from, to) =>
                        edit((x) => ({ ...x, pdos: x.pdos.map((q) => (pdoKey(q) === key ? { ...q, entries: moveItem(q.entries, from, to) } : q)) }))
                      }
                      onComm={(patch) => edit((x) => setComm(x, key, patch))}
                    />
                  );
                })}
              </div>
            );
          })}
        </div>
        <aside className="pdo-side">
          <Palette mappable={mappable} padding={padding} drag={drag} readOnly={readOnly} />
        </aside>
      </div>
    </div>
  );
}
