/**
 * Alarms: the present fault with its meaning, cause and remedy (GET /alarms: 603Fh, or the
 * family's alarm object), the EMCY log with times, the error history (1003h and the family's
 * history objects), the fault reset following the family's procedure (the text comes from
 * the API, e.g. smartris' NMT reset), and clearing the history behind a confirmation.
 *
 * The page reads the alarms again whenever an EMCY arrives or the drive state changes, so a
 * fault appears without a reload.
 */
import { useCallback, useEffect, useState } from 'react';
import { operationApi } from '../api/client';
import type { Alarms } from '../api/types';
import { ConfirmDialog } from '../components/ConfirmDialog';
import { ControlNote, useWriteGate } from '../components/ControlNote';
import { FailureBox } from '../components/FailureBox';
import { StatePill } from '../components/StatePill';
import '../components/operation/operation.css';
import { errorRegisterText, formatEventTime, isResetEntry, newestFirst } from '../lib/alarms';
import { type Failure, failureOf } from '../lib/codes';
import { notify } from '../state/notify';
import { useObservable } from '../state/observable';
import { liveSession, sessions, socket } from '../state/store';
import type { PageProps } from './registry';

export function AlarmsPage({ sid }: PageProps) {
  const list = useObservable(sessions);
  const session = list?.find((s) => s.id === sid) ?? null;
  const live = useObservable(liveSession(sid));
  const [alarms, setAlarms] = useState<Alarms | null>(null);
  const [loadFailure, setLoadFailure] = useState<Failure | null>(null);
  const [actionFailure, setActionFailure] = useState<Failure | null>(null);
  const [busy, setBusy] = useState<'reset' | 'clear' | null>(null);
  const [confirmClear, setConfirmClear] = useState(false);
  // Fault reset and clearing the history change the drive: they need control.
  const noControl = useWriteGate(sid, { write: 'acknowledge_alarms' }).write;

  const load = useCallback(() => {
    operationApi.alarms(sid).then(
      (a) => {
        setAlarms(a);
        setLoadFailure(null);
      },
      (e: unknown) => setLoadFailure(failureOf(e, 'Read the alarms')),
    );
  }, [sid]);

  useEffect(() => {
    const unsub = socket.subscribe(sid);
    const off = socket.on('emcy', (m) => {
      if (m.session === sid) load();
    });
    load();
    return () => {
      unsub();
      off();
    };
  }, [sid, load]);

  // A state change (into or out of Fault) changes what the page shows.
  const stateName = live.state?.state ?? null;
  useEffect(() => {
    if (stateName !== null) load();
  }, [stateName, load]);

  async function reset() {
    setBusy('reset');
    setActionFailure(null);
    try {
      const a = await operationApi.resetAlarms(sid);
      setAlarms(a);
      notify({
        kind: a.current ? 'warning' : 'info',
        title: a.current ? 'Fault reset: the fault is still there' : 'Fault reset done',
        message: a.current ? `${a.current.code_hex} ${a.current.name}: remove the cause first` : a.message ?? `the drive is in ${a.state}`,
        detail: null,
        hint: a.current?.remedy ?? null,
      });
    } catch (e) {
      setActionFailure(failureOf(e, 'Fault reset'));
    } finally {
      setBusy(null);
    }
  }

  async function clearHistory() {
    setBusy('clear');
    setActionFailure(null);
    try {
      setAlarms(await operationApi.clearAlarmHistory(sid));
      setConfirmClear(false);
    } catch (e) {
      setActionFailure(failureOf(e, 'Clear the alarm history'));
      setConfirmClear(false);
    } finally {
      setBusy(null);
    }
  }

  if (list !== null && !session) {
    return (
      <div className="empty" data-testid="no-session">
        Session <span className="mono">{sid}</span> is not open. <a href="#/connect">Open it on the Connect page.</a>
      </div>
    );
  }

  const cur = alarms?.current ?? null;
  const state = stateName ?? alarms?.state ?? null;
  const log = alarms ? newestFirst(alarms.emcy_log) : [];

  return (
    <div className="stack" data-testid="alarms-page">
      {loadFailure && <FailureBox f={loadFailure} testid="alarms-load-error" />}
      <section className={`card${cur ? ' card-fault' : ''}`} data-testid="current-alarm">
        <h2>
          Current alarm
          <span className="h2-side">
            <StatePill state={state} testid="alarms-state" />
          </span>
        </h2>
        {!alarms ? (
          <div className="muted">Reading the alarms…</div>
        ) : cur ? (
          <table className="kv">
            <tbody>
              <tr>
                <th>Alarm</th>
                <td data-testid="alarm-name">
                  <span className="mono big" data-testid="alarm-code">
                    {cur.display ?? cur.code_hex}
                  </span>{' '}
                  <strong>{cur.name}</strong> <span className="muted">· {cur.kind ?? 'fault'} · table {cur.table}</span>
                </td>
              </tr>
              <tr>
                <th>Cause</th>
                <td data-testid="alarm-cause">{cur.cause ?? <span className="muted">the manual gives no cause for this code</span>}</td>
              </tr>
              <tr>
                <th>Remedy</th>
                <td data-testid="alarm-remedy">{cur.remedy ?? <span className="muted">the manual gives no remedy for this code</span>}</td>
              </tr>
              {cur.section && (
                <tr>
                  <th>Manual</th>
                  <td className="muted">{cur.section}</td>
                </tr>
              )}
            </tbody>
          </table>
        ) : (
          <div className="no-alarm" data-testid="no-alarm">
            No alarm: the drive reports no fault{state ? ` (${state})` : ''}.
          </div>
        )}
        <div className="reset-box">
          <div>
            <button
              type="button"
              className="primary"
              data-testid="fault-reset"
              disabled={busy !== null || !alarms || noControl !== null}
              title={noControl ?? undefined}
              onClick={() => void reset()}
            >
              {busy === 'reset' ? 'Resetting…' : 'Fault reset'}
            </button>
          </div>
          <div className="small">
            <span className="hint-label">Procedure for this family:</span>{' '}
            <span data-testid="reset-procedure">{alarms?.reset_procedure ?? '—'}</span>
            <div className="muted">Remove the cause first: a fault whose cause is still there comes back at once.</div>
          </div>
        </div>
        <ControlNote sid={sid} what="Fault reset and Clear history are disabled" rights={{ write: 'acknowledge_alarms' }} />
        {actionFailure && <FailureBox f={actionFailure} testid="alarms-error" />}
      </section>

      <section className="card" data-testid="emcy-log">
        <h2>
          EMCY log <span className="h2-side muted">emergency messages received since the session opened · newest first</span>
        </h2>
        {log.length === 0 ? (
          <div className="muted">No emergency message received.</div>
        ) : (
          <table className="grid">
            <thead>
              <tr>
                <th>Time</th>
                <th>Code</th>
                <th>Name</th>
                <th>Error register (1001h)</th>
                <th>Cause / remedy</th>
              </tr>
            </thead>
            <tbody>
              {log.map((e, i) => (
                <tr key={`${e.time}-${e.code}-${i}`} data-testid="emcy-row" className={isResetEntry(e) ? 'emcy-reset' : ''}>
                  <td className="mono nowrap">{formatEventTime(e.time)}</td>
                  <td className="mono">{e.code_hex}</td>
                  <td>{e.name ?? '—'}</td>
                  <td className="mono small">
                    0x{e.register.toString(16).toUpperCase().padStart(2, '0')} <span className="muted">{errorRegisterText(e.register)}</span>
                  </td>
                  <td className="small">
                    {e.cause && <div>{e.cause}</div>}
                    {e.remedy && (
                      <div>
                        <span className="hint-label">Remedy:</span> {e.remedy}
                      </div>
                    )}
                  </td>
                </tr>
              ))}
            </tbody>
          </table>
        )}
      </section>

      <section className="card" data-testid="error-history">
        <h2>
          Error history
          <span className="h2-side">
            {alarms?.can_clear_history ? (
              <button
                type="button"
                className="small-btn"
                data-testid="clear-history"
                disabled={busy !== null || noControl !== null}
                title={noControl ?? undefined}
                onClick={() => setConfirmClear(true)}
              >
                Clear history…
              </button>
            ) : alarms ? (
              <span className="muted">this family documents no way to clear it</span>
            ) : null}
          </span>
        </h2>
        {!alarms || alarms.history.length === 0 ? (
          <div className="muted" data-testid="history-empty">
            {alarms ? 'The drive holds no error history entries.' : '—'}
          </div>
        ) : (
          <table className="grid">
            <thead>
              <tr>
                <th>Source</th>
                <th>#</th>
                <th>Code</th>
                <th>Name</th>
                <th>Cause / remedy</th>
                <th>Time</th>
              </tr>
            </thead>
            <tbody>
              {alarms.history.map((h, i) => (
                <tr key={`${h.source}-${h.index}-${i}`} data-testid="history-entry">
                  <td className="mono">{h.source}</td>
                  <td className="mono">{h.index}</td>
                  <td className="mono">{h.code_hex}</td>
                  <td>{h.name}</td>
                  <td className="small">
                    {h.cause && <div>{h.cause}</div>}
                    {h.remedy && (
                      <div>
                        <span className="hint-label">Remedy:</span> {h.remedy}
                      </div>
                    )}
                  </td>
                  <td className="mono small">{h.time_h != null ? `${h.time_h} h` : '—'}</td>
                </tr>
              ))}
            </tbody>
          </table>
        )}
        <div className="muted small">1003h: newest entry first (CiA 301 §7.5.2.3); family objects as the manual numbers them.</div>
      </section>

      {confirmClear && (
        <ConfirmDialog
          title="Clear the alarm history?"
          confirmLabel="Clear the history"
          busy={busy === 'clear'}
          onCancel={() => setConfirmClear(false)}
          onConfirm={() => void clearHistory()}
          testid="clear-dialog"
        >
          <p>
            The drive's error history ({alarms?.history.length ?? 0} entr{alarms?.history.length === 1 ? 'y' : 'ies'}) is erased and cannot be
            restored. Keep a copy first if a service report needs it.
          </p>
        </ConfirmDialog>
      )}
    </div>
  );
}
