/**
 * The restore wizard (docs/api.md "Backup, compare, restore"): choose a backup → preflight
 * (writes nothing; every problem with its hint, a failed one disables Restore; the counts; the
 * name mapping for a backup of another family, opt-in) → options (dry run, store to
 * non-volatile memory, force) → run with per-item progress from the WebSocket → the report:
 * every entry's status, the abort code and its meaning for failures, "Resume" for an
 * interrupted restore, and the automatic pre-restore backup. A restore (dry run included) and
 * a resume need control of the drive: without it Run and Resume are disabled and say why.
 */
import { useEffect, useRef, useState } from 'react';
import { ApiError, backupApi } from '../../api/client';
import type { BackupInfo, ErrorInfo, Preflight, RestoreItem, RestoreReport } from '../../api/types';
import { backupTitle, formatTime } from '../../lib/backupHistory';
import { type ProgressItem, mergeProgressItem, watchBackupProgress } from '../../lib/backupProgress';
import { DEFAULT_OPTIONS, type RestoreOptions, canResume, mappedCount, nothingToWrite, reportVerdict, restoreBlocker, sortItems, statusClass, statusLabel } from '../../lib/backupRestore';
import { type Failure, failureOf, findError } from '../../lib/codes';
import { formatRawBytes } from '../../lib/format';
import { ControlNote, useWriteGate } from '../ControlNote';
import { FailureBox } from '../FailureBox';
import { ProgressBar } from '../ProgressBar';
import { UnreadableList, objectsText } from './UnreadableList';

const STEPS = ['Backup', 'Preflight', 'Options', 'Run', 'Report'] as const;

interface Running {
  fraction: number | null;
  message: string | null;
  items: ProgressItem[];
  restoreId: string | null;
}

/** The restore's steps as the WebSocket reports them, the newest last. */
function LiveSteps({ items }: { items: readonly ProgressItem[] }) {
  const shown = items.slice(-8);
  const first = items.length - shown.length;
  return (
    <div className="bk-table-wrap" style={{ marginTop: 6 }}>
      <table className="grid bk-table" data-testid="restore-live">
        <thead>
          <tr>
            <th className="num">#</th>
            <th>Address</th>
            <th>Name</th>
            <th>Step</th>
            <th>Status</th>
          </tr>
        </thead>
        <tbody>
          {shown.map((i, k) => {
            const last = k === shown.length - 1;
            return (
              <tr key={i.address} data-testid="restore-live-row">
                <td className="mono num muted">{first + k + 1}</td>
                <td className="mono">{i.address}</td>
                <td>{i.name ?? <span className="muted">—</span>}</td>
                <td className="muted small">{i.why ?? ''}</td>
                <td>
                  {i.status ? (
                    <span className={`status ${statusClass(i.status)}`}>{statusLabel(i.status)}</span>
                  ) : (
                    <span className={`status ${last ? 'st-pending' : 'st-neutral'}`}>{last ? 'writing…' : 'sent'}</span>
                  )}
                </td>
              </tr>
            );
          })}
        </tbody>
      </table>
    </div>
  );
}

function Count({ n, label, tone, testid }: { n: number; label: string; tone?: 'bad' | 'go'; testid: string }) {
  return (
    <div className={`count${tone && n > 0 ? ` ${tone}` : ''}`} data-testid={testid}>
      <b>{n}</b>
      <span>{label}</span>
    </div>
  );
}

function ItemsTable({ items, errors, testid }: { items: readonly RestoreItem[]; errors: readonly ErrorInfo[]; testid: string }) {
  return (
    <div className="bk-table-wrap">
      <table className="grid bk-table" data-testid={testid}>
        <thead>
          <tr>
            <th>Status</th>
            <th>Address</th>
            <th>Name</th>
            <th>Drive had (raw hex)</th>
            <th>Backup value (raw hex)</th>
            <th>Abort code · meaning</th>
          </tr>
        </thead>
        <tbody>
          {items.map((i) => {
            const info = i.code != null ? findError(errors, i.code, 'sdo') : null;
            return (
              <tr key={i.address} className={i.status === 'failed' ? 'row-failed' : ''} data-testid="report-row" data-address={i.address} data-status={i.status}>
                <td>
                  <span className={`status ${statusClass(i.status)}`}>{statusLabel(i.status)}</span>
                </td>
                <td className="mono">{i.address}</td>
                <td>{i.name ?? <span className="muted">—</span>}</td>
                <td className="mono small">{formatRawBytes(i.old_raw_hex)}</td>
                <td className="mono small">{formatRawBytes(i.new_raw_hex)}</td>
                <td className={i.status === 'failed' ? 'bad' : ''}>
                  {i.code_hex && (
                    <span className="mono" data-testid="report-code">
                      {i.code_hex}
                    </span>
                  )}
                  {(i.meaning ?? info?.name) && <span data-testid="report-meaning"> {i.meaning ?? info?.name}</span>}
                  {i.message && i.message !== i.meaning && <div className="small muted">{i.message}</div>}
                  {info?.remedy && <div className="small">Remedy: {info.remedy}</div>}
                </td>
              </tr>
            );
          })}
        </tbody>
      </table>
    </div>
  );
}

export function RestoreWizard({
  sid,
  profileId,
  backups,
  selected,
  errors,
  onSelect,
  onShowBackup,
  onComparePre,
  onFinished,
}: {
  sid: string;
  /** The drive's profile: a backup of another one is restored only by name, on opt-in. */
  profileId: string | null;
  backups: readonly BackupInfo[];
  selected: string | null;
  errors: readonly ErrorInfo[];
  onSelect: (bid: string | null) => void;
  /** Highlight a backup in the history (the pre-restore one). */
  onShowBackup: (bid: string) => void;
  onComparePre: (bid: string) => void;
  /** A restore (or dry run) finished or stopped: the drive, the history and the audit changed. */
  onFinished: (r: RestoreReport | null) => void;
}) {
  const gate = useWriteGate(sid);
  const [preflight, setPreflight] = useState<Preflight | null>(null);
  const [checking, setChecking] = useState(false);
  const [mapByName, setMapByName] = useState(false);
  const [options, setOptions] = useState<RestoreOptions>(DEFAULT_OPTIONS);
  const [running, setRunning] = useState<Running | null>(null);
  const [report, setReport] = useState<RestoreReport | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [showQuiet, setShowQuiet] = useState(true);
  const checkSeq = useRef(0);

  const backup = backups.find((b) => b.id === selected) ?? null;

  // A new backup starts the wizard over.
  useEffect(() => {
    setPreflight(null);
    setMapByName(false);
    setReport(null);
    setFailure(null);
    if (selected) void check(selected, false);
    // check is stable enough: it reads only its arguments and sid.
  }, [selected, sid]);

  async function check(bid: string, byName: boolean) {
    const my = ++checkSeq.current;
    setChecking(true);
    setFailure(null);
    try {
      const p = await backupApi.preflight(sid, { backup: bid, map_by_name: byName });
      if (my === checkSeq.current) setPreflight(p);
    } catch (e) {
      if (my === checkSeq.current) {
        setPreflight(null);
        setFailure(failureOf(e, 'Check the restore (preflight)', errors));
      }
    } finally {
      if (my === checkSeq.current) setChecking(false);
    }
  }

  async function execute(resumeId: string | null) {
    if (!selected && !resumeId) return;
    setFailure(null);
    setReport(null);
    const state: Running = { fraction: null, message: resumeId ? 'resuming…' : 'starting…', items: [], restoreId: resumeId };
    setRunning(state);
    const watch = watchBackupProgress(sid, 'restore', (m) => {
      if (m.restoreId) state.restoreId = m.restoreId;
      setRunning((r) => (r ? { ...r, fraction: m.fraction, message: m.message ?? r.message, items: m.item ? mergeProgressItem(r.items, m.item) : r.items, restoreId: m.restoreId ?? r.restoreId } : r));
    });
    let result: RestoreReport | null = null;
    try {
      await watch.ready;
      result = resumeId
        ? await backupApi.resume(resumeId)
        : await backupApi.restore(sid, { backup: selected as string, dry_run: options.dryRun, store: options.dryRun ? false : options.store, force: options.force, map_by_name: mapByName });
      setReport(result);
      // The drive changed: what a restore would write now (usually nothing) is worth seeing.
      if (!resumeId && !options.dryRun && selected) void check(selected, mapByName);
    } catch (e) {
      setFailure(failureOf(e, resumeId ? 'Resume the restore' : options.dryRun ? 'Dry-run the restore' : 'Restore', errors));
      // The restore may have stopped half way (link lost): its report says what was written and
      // lets the person resume. The id comes from the progress messages, when they carry it.
      const rid = state.restoreId;
      if (rid && !(e instanceof ApiError && e.status === 404)) {
        try {
          result = await backupApi.report(rid);
          setReport(result);
        } catch {
          // The failure above says what went wrong; no report to show.
        }
      }
    } finally {
      watch.close();
      setRunning(null);
      onFinished(result);
    }
  }

  const otherFamily = !!backup && !!profileId && backup.profile_id !== profileId;
  const noControl = gate.write;
  const blocker = restoreBlocker(preflight, mapByName, otherFamily);
  const idle = blocker ? null : nothingToWrite(preflight, options.dryRun);
  const step = report ? 4 : running ? 3 : preflight ? (blocker ? 1 : 2) : selected ? 1 : 0;
  const counts = mappedCount(preflight?.mapping ?? null);
  const verdict = report ? reportVerdict(report) : null;
  const preBackup = report?.pre_backup ? (backups.find((b) => b.id === report.pre_backup) ?? null) : null;
  const reportItems = report ? sortItems(report.items).filter((i) => showQuiet || (i.status !== 'unchanged' && i.status !== 'skipped_read_only')) : [];

  return (
    <section className="card" data-testid="restore-wizard">
      <h2>Restore</h2>
      <div className="steps" aria-label="Restore steps">
        {STEPS.map((s, i) => (
          <div key={s} className={`step${i < step ? ' done' : ''}${i === step ? ' current' : ''}`} data-testid={`restore-step-${i + 1}`}>
            {i + 1}. {s}
          </div>
        ))}
      </div>

      <div className="bk-row">
        <label className="bk-row">
          Backup to restore
          <select data-testid="restore-backup" value={selected ?? ''} onChange={(e) => onSelect(e.target.value || null)} disabled={running !== null} style={{ minWidth: 320 }}>
            <option value="">— choose a backup —</option>
            {backups.map((b) => (
              <option key={b.id} value={b.id}>
                {backupTitle(b)} · {b.entries} entries{b.complete ? '' : ` (incomplete: ${b.unreadable.length} unreadable)`} · {b.profile_id}
              </option>
            ))}
            {selected && !backup && <option value={selected}>Backup {selected}</option>}
          </select>
        </label>
        {selected && (
          <button type="button" className="small-btn" onClick={() => void check(selected, mapByName)} disabled={checking || running !== null} data-testid="restore-check">
            {checking ? 'Checking…' : 'Check again'}
          </button>
        )}
      </div>
      {!selected && <div className="muted" style={{ marginTop: 6 }}>Choose a backup here or with “Restore…” in the history.</div>}

      {selected && (
        <div className="wizard-section" data-testid="preflight">
          <h3>Preflight</h3>
          {checking && !preflight && <div className="muted">Checking the backup against the drive…</div>}
          {preflight && (
            <>
              <div className={preflight.ok ? 'bk-ok' : 'bk-bad'} data-testid="preflight-verdict" data-ok={preflight.ok ? 'true' : 'false'}>
                {preflight.ok ? 'The backup fits this drive.' : `The backup cannot be restored as it is: ${preflight.problems.length} problem${preflight.problems.length === 1 ? '' : 's'}.`}
              </div>
              <div className="counts">
                <Count n={preflight.to_write} label="to write" testid="preflight-to-write" />
                <Count n={preflight.unchanged} label="unchanged" testid="preflight-unchanged" />
                <Count n={preflight.read_only_skipped} label="read-only, skipped" testid="preflight-skipped" />
              </div>
              <UnreadableList
                items={preflight.unreadable}
                headline={`This backup is incomplete: a restore cannot set ${objectsText(preflight.unreadable.length)} it lacks (unreadable when it was taken); the drive keeps its present values there.`}
                testid="preflight-unreadable"
              />
              {preflight.warnings && preflight.warnings.length > 0 && (
                <ul className="problems warnings" data-testid="preflight-warnings">
                  {preflight.warnings.map((w, i) => (
                    <li key={i}>{w}</li>
                  ))}
                </ul>
              )}
              {(otherFamily || preflight.mapping || mapByName) && (
                <div className="wizard-section" data-testid="preflight-mapping">
                  <h3>Another drive family: map entries by name</h3>
                  <div className="small" style={{ marginBottom: 6 }}>
                    The backup was taken of {backup ? <span className="mono">{backup.profile_id}</span> : 'another family'}, this drive is{' '}
                    <span className="mono">{profileId ?? '?'}</span>: addresses mean other things here. Entries can be written to the object of the same name instead.
                    {preflight.mapping && (
                      <>
                        {' '}
                        {counts.mapped} mapped, {counts.unmapped} without a match (left out).
                      </>
                    )}
                  </div>
                  <label className="bk-row">
                    <input
                      type="checkbox"
                      data-testid="restore-map-by-name"
                      checked={mapByName}
                      disabled={checking || running !== null}
                      onChange={(e) => {
                        setMapByName(e.target.checked);
                        if (selected) void check(selected, e.target.checked);
                      }}
                    />
                    Map entries by name (I checked the table below)
                  </label>
                  {!preflight.mapping && <div className="muted small">Opt in to see how every entry maps onto this drive.</div>}
                  {preflight.mapping && (
                    <div className="bk-table-wrap">
                      <table className="grid bk-table" data-testid="mapping-table">
                        <thead>
                          <tr>
                            <th>Backup address</th>
                            <th>Name</th>
                            <th>This drive's address</th>
                          </tr>
                        </thead>
                        <tbody>
                          {[...preflight.mapping].sort((x, y) => Number(y.target !== null) - Number(x.target !== null)).map((m) => (
                            <tr key={m.address} data-testid="mapping-row" data-mapped={m.target ? 'true' : 'false'}>
                              <td className="mono">{m.address}</td>
                              <td>{m.name ?? '—'}</td>
                              <td className={m.target ? 'mono' : 'muted'}>{m.target ?? `no match, left out${m.reason ? `: ${m.reason}` : ''}`}</td>
                            </tr>
                          ))}
                        </tbody>
                      </table>
                    </div>
                  )}
                </div>
              )}
              {preflight.problems.length > 0 && (
                <ul className="problems scroll" data-testid="preflight-problems">
                  {preflight.problems.map((p, i) => (
                    <li key={`${p.address ?? ''}-${i}`} data-testid="preflight-problem">
                      {/* The server's message often names the entry already; say it once. */}
                      {p.address && !p.message.includes(p.address) && <span className="mono">{p.address} </span>}
                      {p.name && !p.message.includes(p.name) && <strong>{p.name}: </strong>}
                      {p.message}
                      {p.hint && (
                        <div className="notice-hint">
                          <span className="hint-label">What to do:</span> {p.hint}
                        </div>
                      )}
                    </li>
                  ))}
                </ul>
              )}
            </>
          )}
        </div>
      )}

      {preflight && (
        <div className="wizard-section" data-testid="restore-options">
          <h3>Options</h3>
          <div className="options">
            <label>
              <input type="checkbox" data-testid="restore-dry-run" checked={options.dryRun} onChange={(e) => setOptions({ ...options, dryRun: e.target.checked })} disabled={running !== null} />
              Dry run <span className="muted">— read and compare only; report what would be written, write nothing</span>
            </label>
            <label>
              <input
                type="checkbox"
                data-testid="restore-store"
                checked={options.store && !options.dryRun}
                onChange={(e) => setOptions({ ...options, store: e.target.checked })}
                disabled={running !== null || options.dryRun}
              />
              Store to non-volatile memory <span className="muted">— after every written entry was read back and verified</span>
            </label>
            <label>
              <input type="checkbox" data-testid="restore-force" checked={options.force} onChange={(e) => setOptions({ ...options, force: e.target.checked })} disabled={running !== null} />
              Force <span className="muted">— store to non-volatile memory even if some entries failed (the rest stays as verified)</span>
            </label>
          </div>
          <div className="bk-row" style={{ marginTop: 8 }}>
            <button
              type="button"
              className={options.dryRun ? 'primary' : 'warn-btn'}
              data-testid="restore-run"
              disabled={blocker !== null || idle !== null || running !== null || checking || noControl !== null}
              onClick={() => void execute(null)}
              title={blocker ?? idle ?? noControl ?? undefined}
            >
              {running ? 'Restoring…' : options.dryRun ? 'Dry run' : `Restore ${preflight.to_write} entr${preflight.to_write === 1 ? 'y' : 'ies'}`}
            </button>
            {blocker && (
              <span className="warn-text small" data-testid="restore-blocked">
                Restore is disabled: {blocker}.
              </span>
            )}
            {idle && (
              <span className="muted small" data-testid="restore-nothing">
                Restore is disabled: {idle}.
              </span>
            )}
            {!blocker && !idle && !options.dryRun && <span className="muted small">servodesk takes a backup of the drive first, so this can be undone.</span>}
          </div>
          <ControlNote sid={sid} what="Restore (and its dry run) is disabled; the preflight works" testid="restore-control-note" />
        </div>
      )}

      {running && (
        <div className="wizard-section" data-testid="restore-running">
          <h3>Running</h3>
          <ProgressBar fraction={running.fraction} label={running.message ?? undefined} testid="restore-progress" />
          {running.items.length > 0 && <LiveSteps items={running.items} />}
        </div>
      )}

      {failure && (
        <div style={{ marginTop: 8 }}>
          <FailureBox f={failure} testid="restore-failure" />
        </div>
      )}

      {report && verdict && (
        <div className="wizard-section" data-testid="restore-report" data-finished={report.finished ? 'true' : 'false'}>
          <h3>
            Report <span className="muted small mono">{report.id}</span> <span className="muted small">{formatTime(report.time)}</span>
          </h3>
          <div className={verdict.kind === 'ok' ? 'bk-ok' : verdict.kind === 'warn' ? 'bk-warn' : 'bk-bad'} data-testid="report-verdict">
            {verdict.text}
            {report.message && <div className="small" data-testid="report-message">{report.message}</div>}
          </div>
          <div className="counts">
            {report.dry_run ? (
              <Count n={report.items.filter((i) => i.status === 'would_write').length} label="would write" tone="go" testid="report-would-write" />
            ) : (
              <Count n={report.counts.written} label="written" tone="go" testid="report-written" />
            )}
            <Count n={report.counts.unchanged} label="unchanged" testid="report-unchanged" />
            <Count n={report.counts.skipped} label="skipped" testid="report-skipped" />
            <Count n={report.counts.failed} label="failed" tone="bad" testid="report-failed" />
            <Count n={report.counts.pending} label="pending" tone="bad" testid="report-pending" />
            <div className="count">
              <b data-testid="report-stored">{report.stored ? 'yes' : 'no'}</b>
              <span>stored</span>
            </div>
          </div>
          <UnreadableList
            items={report.unreadable}
            headline={`${report.dry_run ? 'Would not restore' : 'Not restored'}: ${objectsText(report.unreadable.length)} the backup lacks (unreadable when it was taken); the drive keeps its present values there.`}
            testid="report-unreadable"
          />
          {report.pre_backup && (
            <div className="bk-row small" data-testid="report-pre-backup" style={{ marginBottom: 6 }}>
              Pre-restore backup (taken automatically):{' '}
              <a
                href="#"
                data-testid="report-pre-backup-link"
                onClick={(e) => {
                  e.preventDefault();
                  onShowBackup(report.pre_backup as string);
                }}
              >
                {preBackup ? backupTitle(preBackup) : report.pre_backup}
              </a>
              <button type="button" className="small-btn" onClick={() => onComparePre(report.pre_backup as string)}>
                Compare with the live drive
              </button>
              <button type="button" className="small-btn" onClick={() => onSelect(report.pre_backup)} title="Restore the state before this restore">
                Undo: restore it…
              </button>
            </div>
          )}
          {canResume(report) && (
            <div className="bk-row" style={{ marginBottom: 6 }}>
              <button
                type="button"
                className="warn-btn"
                data-testid="restore-resume"
                onClick={() => void execute(report.id)}
                disabled={running !== null || noControl !== null}
                title={noControl ?? undefined}
              >
                Resume ({report.counts.pending} left)
              </button>
              <span className="muted small">continues with the entries not yet verified</span>
            </div>
          )}
          <label className="bk-row small" style={{ marginBottom: 4 }}>
            <input type="checkbox" checked={showQuiet} onChange={(e) => setShowQuiet(e.target.checked)} /> Also list unchanged and skipped entries
          </label>
          <ItemsTable items={reportItems} errors={errors} testid="report-table" />
        </div>
      )}
    </section>
  );
}
