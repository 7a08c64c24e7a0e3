/**
 * Tuning (issue 8, docs/tuning.md): a wizard over the tuning service.
 *
 * 1. What this family can do: the drive's own one-touch tuning (LECSN-T), servodesk's own
 *    tuning (a gain map), or plainly nothing, with what applies instead.
 * 2. Safety inputs: the travel window (rev, and in position units around where the axis
 *    stands), the torque limit, the response mode, and the confirmation that the axis may move.
 * 3. Run: Start, a progress bar with the step, and STOP one click away (sticky while it runs).
 * 4. Result: the decoded error (cause and remedy), identified values, the Bode plot when there
 *    is one, the step responses before and after, the gain table old -> new with raw values,
 *    Undo (to the gains before / the defaults) and Store to EEPROM, each after a confirmation.
 *
 * Tuning moves the axis under this tab's dead-man, like a jog on the Operation page: the page
 * sends the heartbeat while the job's motion runs, and leaving the page stops the tuning.
 */
import { useCallback, useEffect, useMemo, useState } from 'react';
import { api, operationApi } from '../api/client';
import { type Refit, type TuningInfo, type TuningJob, type TuningMode, type TuningResult, tuningApi } from '../api/tuning';
import { ConfirmDialog } from '../components/ConfirmDialog';
import { FailureBox } from '../components/FailureBox';
import { ProgressBar } from '../components/ProgressBar';
import { StatePill } from '../components/StatePill';
import { ControlCard } from '../components/operation/ControlCard';
import { ControlNote, useWriteGate } from '../components/ControlNote';
import { beginHeartbeat, heartbeatRunning, loadControl, me, operationLive, startAnswered, startOperationStore, stopHeartbeat } from '../components/operation/operationStore';
import '../components/operation/operation.css';
import { GainTable } from '../components/tuning/GainTable';
import { TuningHistory } from '../components/tuning/TuningHistory';
import { BodePlot, StepPlot } from '../components/tuning/TuningPlots';
import { type Inputs, boundText, checkInputs, confirmationText, fmtNumber, gainLines, isRunning, jobLabel, kindTitle, modeText, presentLines, refitLines, windowInUnits, withUnit } from '../components/tuning/tuningModel';
import '../components/tuning/tuning.css';
import { type Failure, failureOf } from '../lib/codes';
import { notify, notifyError } from '../state/notify';
import { useObservable } from '../state/observable';
import { partHref } from '../state/router';
import { applyState, liveSession, sessions, socket, socketStatus } from '../state/store';
import type { PageProps } from './registry';

type Confirm = 'undo-before' | 'undo-defaults' | 'store' | null;

function Step({ n, title, children, testid, dim = false }: { n: number; title: string; children: React.ReactNode; testid: string; dim?: boolean }) {
  return (
    <section className={`card tuning-step${dim ? ' dim' : ''}`} data-testid={testid}>
      <h2>
        <span className="tuning-n">{n}</span> {title}
      </h2>
      {children}
    </section>
  );
}

/** The inertias the winner's try fitted, and what servodesk did with them (own tuning). */
function RefitRow({ refit }: { refit: Refit }) {
  const { fit, outcome } = refitLines(refit);
  return (
    <tr data-testid="tuning-refit">
      <th>Inertias fitted to the winner's try</th>
      <td className="mono">
        {fit}
        <div className="muted small" data-testid="tuning-refit-outcome">
          {outcome}
        </div>
      </td>
    </tr>
  );
}

function ErrorBlock({ error, testid }: { error: NonNullable<TuningResult['error']>; testid: string }) {
  return (
    <div className="failure" role="alert" data-testid={testid}>
      <div className="failure-title">
        {error.code_hex ? (
          <span className="mono" data-testid={`${testid}-code`}>
            {error.code_hex}{' '}
          </span>
        ) : null}
        <span data-testid={`${testid}-name`}>{error.name}</span>
      </div>
      {error.cause && (
        <div data-testid={`${testid}-cause`}>
          <span className="hint-label">Cause:</span> {error.cause}
        </div>
      )}
      {error.remedy && (
        <div data-testid={`${testid}-remedy`}>
          <span className="hint-label">Remedy:</span> {error.remedy}
        </div>
      )}
      {error.section ? <div className="muted small">Manual: {error.section}</div> : null}
    </div>
  );
}

export function TuningPage({ sid }: PageProps) {
  const list = useObservable(sessions);
  const session = list?.find((s) => s.id === sid) ?? null;
  const live = useObservable(liveSession(sid));
  const ws = useObservable(socketStatus);
  const op = useObservable(operationLive(sid));
  const gate = useWriteGate(sid, { write: 'tune', energise: 'tune' });
  const state = live.state;
  const [info, setInfo] = useState<TuningInfo | null>(null);
  const [infoFailure, setInfoFailure] = useState<Failure | null>(null);
  const [job, setJob] = useState<TuningJob | null>(null);
  const [result, setResult] = useState<TuningResult | null>(null);
  const [inputs, setInputs] = useState<Inputs | null>(null);
  const [confirmed, setConfirmed] = useState(false);
  const [busy, setBusy] = useState<string | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [confirm, setConfirm] = useState<Confirm>(null);
  const [undoNote, setUndoNote] = useState<string | null>(null);

  const loadInfo = useCallback(() => {
    tuningApi.info(sid).then(
      (i) => {
        setInfo(i);
        setInfoFailure(null);
        setJob(i.job);
        setInputs((prev) => prev ?? { mode: i.defaults.mode, travel: String(i.defaults.travel_window_rev), torque: String(i.defaults.torque_limit_pct), moveTorque: '' });
        if (i.result_available) tuningApi.result(sid).then(setResult, () => undefined);
      },
      (e: unknown) => setInfoFailure(failureOf(e, 'Read the tuning')),
    );
  }, [sid]);

  useEffect(() => {
    startOperationStore();
    const unsub = socket.subscribe(sid);
    let alive = true;
    api.state(sid).then(
      (s) => alive && applyState(sid, s),
      () => undefined,
    );
    loadControl(sid);
    loadInfo();
    const off = socket.on('tuning', (m) => {
      if (m.session !== sid) return;
      setJob(m.job);
      if (m.job.state !== 'running') {
        if (m.job.owner === me()) stopHeartbeat(sid);
        tuningApi.result(sid).then(setResult, () => undefined);
        tuningApi.info(sid).then(setInfo, () => undefined);
      }
    });
    return () => {
      alive = false;
      off();
      unsub();
      // A tuning started here does not outlive the page: leaving it stops the tuning.
      if (heartbeatRunning(sid)) {
        stopHeartbeat(sid);
        tuningApi.stop(sid).catch(notifyError);
      }
    };
  }, [sid, loadInfo]);

  // A job that ended while a message was missed (socket down): poll while one runs.
  useEffect(() => {
    if (!isRunning(job)) return;
    const t = setInterval(() => {
      tuningApi.info(sid).then((i) => {
        if (!isRunning(i.job)) {
          setJob(i.job);
          setInfo(i);
          if (i.job?.owner === me()) stopHeartbeat(sid);
          tuningApi.result(sid).then(setResult, () => undefined);
        }
      }, () => undefined);
    }, 2000);
    return () => clearInterval(t);
  }, [sid, job]);

  const check = useMemo(() => (info && inputs ? checkInputs(inputs, info) : null), [info, inputs]);

  if (list !== null && !session) {
    return (
      <div className="empty" data-testid="no-session">
        Session <span className="mono">{sid}</span> is not open. <a href="#/connect">Open it on the Connect page.</a>
      </div>
    );
  }
  if (infoFailure) return <FailureBox f={infoFailure} testid="tuning-info-error" />;
  if (!info || !inputs) return <div className="muted">Reading what this drive can tune…</div>;

  const running = isRunning(job);
  // Control is this tab's token (state/control); the tuning moves the axis, so it also needs
  // this tab's WebSocket bound as the dead-man.
  const you = gate.view.you && gate.view.bind.state === 'bound';
  const writeOk = gate.write === null;
  const enabled = state?.state === 'Operation enabled';
  const socketOpen = ws.status === 'open';
  const pos = info.position;
  const win = check?.travelRev != null && pos.actual !== null ? windowInUnits(check.travelRev, pos.units_per_rev, pos.actual) : null;
  const canStart = !running && !!check?.ok && confirmed && you && enabled && socketOpen && busy === null;

  function set<K extends keyof Inputs>(key: K, value: Inputs[K]) {
    setInputs((prev) => (prev ? { ...prev, [key]: value } : prev));
    setConfirmed(false); // A changed window needs a new confirmation.
  }

  async function start() {
    if (!check?.ok || check.travelRev === null || check.torquePct === null || !inputs) return;
    setFailure(null);
    setUndoNote(null);
    setBusy('start');
    beginHeartbeat(sid); // Before the request: the dead-man counts from its arrival.
    try {
      const body = { mode: inputs.mode, travel_window_rev: check.travelRev, torque_limit_pct: check.torquePct };
      const j = await tuningApi.start(sid, info?.kind === 'gains' && check.moveTorquePct !== null ? { ...body, move_torque_pct: check.moveTorquePct } : body);
      setJob(j);
      setResult(null);
      setConfirmed(false); // The next run is confirmed again.
      startAnswered(sid, await operationApi.motion(sid));
    } catch (e) {
      stopHeartbeat(sid);
      setFailure(failureOf(e, 'Start the tuning'));
    } finally {
      setBusy(null);
    }
  }

  async function stop() {
    setBusy('stop');
    try {
      setJob(await tuningApi.stop(sid));
    } catch (e) {
      notifyError(e);
    } finally {
      stopHeartbeat(sid);
      setBusy(null);
    }
  }

  async function confirmed_(what: Exclude<Confirm, null>) {
    setBusy(what);
    setFailure(null);
    try {
      if (what === 'store') {
        const r = await tuningApi.store(sid);
        notify({ kind: 'info', title: 'Stored to EEPROM', message: `${r.procedure} in ${r.duration_s} s`, detail: null, hint: null });
      } else {
        const u = await tuningApi.undo(sid, what === 'undo-before' ? 'before' : 'defaults');
        setUndoNote(u.note);
      }
      setConfirm(null);
      loadInfo();
      tuningApi.result(sid).then(setResult, () => undefined);
    } catch (e) {
      setConfirm(null);
      setFailure(failureOf(e, what === 'store' ? 'Store to EEPROM' : 'Undo'));
    } finally {
      setBusy(null);
    }
  }

  const stepBefore = result?.step?.before ?? null;
  const stepAfter = result?.step?.after ?? null;
  const resultError = result?.error ?? null;

  return (
    <div className="stack tuning-page" data-testid="tuning-page" data-kind={info.kind}>
      {running && job && (
        <div className="stop-bar tuning-bar" data-testid="tuning-bar">
          <div className="stop-live">
            <StatePill state={state?.state ?? null} />
            <span className="stop-val">
              <span className="muted">Position</span> <span className="mono">{state?.position ?? '—'}</span> <span className="unit">{state?.position_raw_unit ?? ''}</span>
            </span>
            <span className="stop-val small">{jobLabel(job)}</span>
            {op.heartbeat.running && (
              <span className={`badge ${op.heartbeat.missed > 0 ? 'badge-bad' : 'badge-hb'}`} data-testid="heartbeat-indicator">
                {op.heartbeat.missed > 0 ? `heartbeat NOT sent (${op.heartbeat.missed})` : 'heartbeat ♥'}
              </span>
            )}
          </div>
          <div className="stop-buttons">
            <button type="button" className="qs-btn" onClick={() => void stop()} data-testid="tuning-stop">
              STOP TUNING
            </button>
          </div>
        </div>
      )}

      {op.deadman && (
        <div className="deadman-banner" role="alert" data-testid="deadman-banner">
          <div>
            <strong>The dead-man stopped the tuning motion.</strong> {op.deadman.reason}
          </div>
        </div>
      )}

      <Step n={1} title={`What this drive can do: ${kindTitle(info.kind)}`} testid="tuning-kind">
        <div className="tuning-kind" data-testid="tuning-kind-text" data-kind={info.kind}>
          <span className={`badge ${info.kind === 'none' ? 'badge-neutral' : 'badge-go'}`}>{info.kind}</span> {info.reason}
        </div>
        {info.kind === 'none' ? (
          <div className="tuning-applies" data-testid="tuning-applies">
            <span className="muted">What applies instead: </span>
            {info.applies.map((a) => (
              <a key={a.label} href={partHref(a.page, sid, a.group)} className="chip" data-testid={`tuning-applies-${a.group || 'page'}`}>
                {a.label}
              </a>
            ))}
          </div>
        ) : (
          <>
            <GainTable lines={presentLines(info.gains)} compare={false} testid="tuning-present-gains" />
            <div className="muted small">
              {info.loop_rate_hz ? `Servo loop ${fmtNumber(info.loop_rate_hz)} Hz. ` : ''}
              {info.undo.note}
            </div>
          </>
        )}
      </Step>

      {info.kind !== 'none' && (
        <>
          <div className="op-grid">
            <div className="stack">
              <Step n={2} title="Safety inputs" testid="tuning-inputs">
                <div className="op-fields">
                  <label className="op-field">
                    Travel window [rev]
                    <input
                      type="text"
                      inputMode="decimal"
                      value={inputs.travel}
                      disabled={running}
                      onChange={(e) => set('travel', e.target.value)}
                      data-testid="tuning-travel"
                    />
                    <span className="small" data-testid="tuning-window-units">
                      {win ? `total width, centred where the axis stands: ${boundText(win, pos)}` : 'position unknown'}
                    </span>
                    {check?.travel && <span className="inline-error">{check.travel}</span>}
                  </label>
                  <label className="op-field">
                    Torque limit [% of rated]
                    <input
                      type="text"
                      inputMode="decimal"
                      value={inputs.torque}
                      disabled={running}
                      onChange={(e) => set('torque', e.target.value)}
                      data-testid="tuning-torque"
                    />
                    <span className="small">
                      {info.kind === 'gains'
                        ? "passed to servodesk's tuning"
                        : info.torque_limit.object
                          ? `written to ${info.torque_limit.object} for the run${info.torque_limit.present_pct !== null ? `; now ${fmtNumber(info.torque_limit.present_pct)} %` : ''}`
                          : 'this drive has no torque limit object: not applied'}
                    </span>
                    {check?.torque && <span className="inline-error">{check.torque}</span>}
                  </label>
                  {info.kind === 'gains' && (
                    <label className="op-field">
                      Machine's move: peak torque [% of rated]
                      <input
                        type="text"
                        inputMode="decimal"
                        value={inputs.moveTorque ?? ''}
                        placeholder="= torque limit"
                        disabled={running}
                        onChange={(e) => set('moveTorque', e.target.value)}
                        data-testid="tuning-move-torque"
                      />
                      <span className="small">
                        optional: the torque your machine's own moves accelerate with; the gains are chosen for a 0.5 rev
                        move at 70 % of it (only computed, the axis never gets more than the torque limit)
                      </span>
                      {check?.moveTorque && <span className="inline-error">{check.moveTorque}</span>}
                    </label>
                  )}
                </div>
                <div className="tuning-modes" role="radiogroup" aria-label="Response mode">
                  {info.modes.map((m: TuningMode) => (
                    <label key={m} className="op-check">
                      <input type="radio" name="tuning-mode" checked={inputs.mode === m} disabled={running} onChange={() => set('mode', m)} data-testid={`tuning-mode-${m}`} />
                      {modeText(m, info.mode_notes)}
                    </label>
                  ))}
                </div>
                {info.travel_rule && (
                  <div className="muted small" data-testid="tuning-travel-rule">
                    {info.travel_rule}
                  </div>
                )}
                <div className="muted small">
                  1 rev = {fmtNumber(pos.units_per_rev, 8)} {pos.raw_unit} ({pos.units_per_rev_source}). Software limits:{' '}
                  {pos.min === null && pos.max === null ? 'none' : `${pos.min ?? '−∞'} … ${pos.max ?? '+∞'}`}
                  {pos.limits_source ? ` (${pos.limits_source})` : ''}.
                </div>
                {check?.window && (
                  <div className="inline-error" data-testid="tuning-window-error">
                    {check.window}
                  </div>
                )}
                <label className="op-check tuning-confirm">
                  <input type="checkbox" checked={confirmed} disabled={running || !check?.ok} onChange={(e) => setConfirmed(e.target.checked)} data-testid="tuning-confirm" />
                  <span data-testid="tuning-confirm-text">
                    {win
                      ? confirmationText(info.kind, win, pos, check?.torquePct ?? null)
                      : `The axis moves inside the travel window around where it stands, with up to ${check?.torquePct ?? '—'} % torque; the area is clear.`}
                  </span>
                </label>
              </Step>

              <Step n={3} title="Run" testid="tuning-run">
                {!you && (
                  <div className="op-note" data-testid="tuning-no-control">
                    {gate.view.owner && !gate.view.you
                      ? `Client ${gate.view.owner} holds control: tuning from this tab is refused.`
                      : gate.view.you
                        ? `The tuning is disabled: ${gate.energise ?? "this tab's dead-man link is not bound"}.`
                        : 'Take control first (Take control, top right): the tuning moves the axis.'}
                  </div>
                )}
                {you && !enabled && <div className="op-note">The servo is off ({state?.state ?? 'unknown'}): press Servo on below.</div>}
                {!socketOpen && <div className="op-note">No live connection to the server: the tuning needs this tab's WebSocket for its dead-man heartbeat.</div>}
                <div className="op-row">
                  <button type="button" className="primary" disabled={!canStart} onClick={() => void start()} data-testid="tuning-start">
                    {busy === 'start' ? 'Starting…' : 'Start tuning'}
                  </button>
                  {running && (
                    <button type="button" className="danger" onClick={() => void stop()} data-testid="tuning-stop-inline">
                      Stop
                    </button>
                  )}
                </div>
                {job && (
                  <div className="tuning-progress" data-testid="tuning-job" data-state={job.state}>
                    <ProgressBar fraction={job.progress} label={`${Math.round(job.progress * 100)} %`} testid="tuning-progress" />
                    <div className="small" data-testid="tuning-step-text">
                      {job.step}
                    </div>
                    {job.bound?.text && (
                      <div className="small muted" data-testid="tuning-job-bound">
                        Travel bound as the server holds it: {job.bound.text}
                      </div>
                    )}
                    {job.state !== 'running' && job.message && <div className="small muted">{job.message}</div>}
                  </div>
                )}
                {failure && <FailureBox f={failure} testid="tuning-failure" />}
              </Step>
            </div>
            <div className="stack">
              <ControlCard sid={sid} state={state} socketOpen={socketOpen} />
            </div>
          </div>

          <Step n={4} title="Result" testid="tuning-result" dim={!result}>
            {!result ? (
              <div className="muted">No tuning result yet in this session.</div>
            ) : (
              <div className="stack">
                <div data-testid="tuning-result-status" data-status={result.status}>
                  <strong>
                    {result.status === 'done' ? 'Tuning finished normally.' : result.status === 'stopped' ? 'Tuning stopped.' : 'Tuning failed.'}
                  </strong>{' '}
                  <span className="muted">
                    Mode {result.mode}; the axis moved for {withUnit(result.axis_time_s, 's')},{' '}
                    {result.travel?.max_excursion_rev != null
                      ? `at most ${withUnit(result.travel.max_excursion_rev, 'rev')} (${result.travel.max_excursion ?? '—'} ${result.travel.raw_unit ?? 'counts'}) from the start, within ${result.travel.text ?? `±${result.travel.half}`}`
                      : `over a span of ${withUnit(result.excursion_rev, 'rev')}${result.travel?.text ? ` inside ${result.travel.text}` : ''}`}
                    {result.peak_torque_pct !== null
                      ? result.peak_torque_polled_s
                        ? `, peak torque ${fmtNumber(result.peak_torque_pct)} % of the rated torque in 6077h read every ${fmtNumber(result.peak_torque_polled_s)} s (a shorter peak, such as an acceleration's, is not seen)`
                        : `, peak torque ${fmtNumber(result.peak_torque_pct)} % of the rated torque`
                      : ''}
                    .{' '}
                    {result.applied ? 'The new gains are active.' : 'The gains from before are active.'} {result.stored ? 'Stored to EEPROM.' : 'Not stored.'}
                    {result.undone ? ` Undone (${result.undone === 'before' ? 'to the gains before tuning' : 'to the defaults'}).` : ''}
                  </span>
                </div>
                {resultError && <ErrorBlock error={resultError} testid="tuning-error" />}
                {result.identified && (result.identified.inertia_ratio !== null || result.identified.inertia_kgm2 !== null) && (
                  <table className="grid" data-testid="tuning-identified">
                    <tbody>
                      {result.identified.inertia_ratio !== null && (
                        <tr>
                          <th>Load to motor inertia ratio</th>
                          <td className="mono num">{fmtNumber(result.identified.inertia_ratio)}</td>
                        </tr>
                      )}
                      {result.identified.inertia_kgm2 !== null && (
                        <tr>
                          <th>Inertia</th>
                          <td className="mono num">{withUnit(result.identified.inertia_kgm2, 'kg m²')}</td>
                        </tr>
                      )}
                      {result.identified.moves_friction_nm != null && result.identified.moves_speed_rad_s != null && (
                        <tr data-testid="tuning-moves-friction">
                          <th>Friction at the test moves' speed</th>
                          <td className="mono num">
                            {withUnit(result.identified.moves_friction_nm, 'N m')} at {withUnit(result.identified.moves_speed_rad_s / (2 * Math.PI), 'rev/s')} (
                            {withUnit(result.identified.moves_speed_rad_s, 'rad/s')})
                          </td>
                        </tr>
                      )}
                      {result.identified.coulomb_nm !== null && (
                        <tr>
                          <th>Coulomb friction (test moves' fit)</th>
                          <td className="mono num">{withUnit(result.identified.coulomb_nm, 'N m')}</td>
                        </tr>
                      )}
                      {result.identified.travel_friction_nm != null && (
                        <tr data-testid="tuning-travel-friction">
                          <th>Coulomb friction (slow travel)</th>
                          <td className="mono num">{withUnit(result.identified.travel_friction_nm, 'N m')}</td>
                        </tr>
                      )}
                      {result.identified.ranking_friction_nm != null && (
                        <tr data-testid="tuning-ranking-friction">
                          <th>Coulomb friction the ranking used</th>
                          <td className="mono num">{withUnit(result.identified.ranking_friction_nm, 'N m')}</td>
                        </tr>
                      )}
                      {result.identified.viscous_nms !== null && (
                        <tr data-testid="tuning-viscous">
                          <th>Viscous friction (test moves' fit)</th>
                          <td className="mono num">
                            {withUnit(result.identified.viscous_nms, 'N m s/rad')}
                            {result.identified.moves_speed_rad_s != null && (
                              <div className="muted small">
                                The moves run at one speed, where the fit cannot tell Coulomb from viscous friction (it may trade them, to a negative
                                viscous term): their sum at that speed, above, is what they measured.
                              </div>
                            )}
                          </td>
                        </tr>
                      )}
                      {result.identified.gravity_nm !== null && (
                        <tr>
                          <th>Gravity load</th>
                          <td className="mono num">{withUnit(result.identified.gravity_nm, 'N m')}</td>
                        </tr>
                      )}
                      {result.identified.resonances.map((r) => (
                        <tr key={r.freq_hz}>
                          <th>Resonance</th>
                          <td className="mono num">
                            {withUnit(r.freq_hz, 'Hz')}
                            {r.anti_freq_hz !== null ? ` (anti-resonance ${withUnit(r.anti_freq_hz, 'Hz')})` : ''}
                            {r.peak_db !== null ? `, ${withUnit(r.peak_db, 'dB')}` : ''}
                            {r.damping !== undefined ? `, damping ${r.damping.toFixed(4)}` : ''}
                          </td>
                        </tr>
                      ))}
                      {result.identified.refit && <RefitRow refit={result.identified.refit} />}
                    </tbody>
                  </table>
                )}
                {result.margins && (
                  <div className="small" data-testid="tuning-margins">
                    Phase margin {withUnit(result.margins.phase_margin_deg, '°')}, gain margin {withUnit(result.margins.gain_margin_db, 'dB')}, crossover{' '}
                    {withUnit(result.margins.crossover_hz, 'Hz')}, bandwidth {withUnit(result.margins.bandwidth_hz, 'Hz')}
                  </div>
                )}
                {result.bode && <BodePlot bode={result.bode} />}
                {(stepBefore || stepAfter) && (
                  <div>
                    <h3 className="tuning-h3">Step response before and after</h3>
                    <StepPlot before={stepBefore} after={stepAfter} />
                    <table className="grid small" data-testid="tuning-step-metrics">
                      <thead>
                        <tr>
                          <th />
                          <th className="num">Settling</th>
                          <th className="num">Overshoot</th>
                          <th className="num">Following error RMS</th>
                          <th>Recorded by</th>
                        </tr>
                      </thead>
                      <tbody>
                        {(
                          [
                            ['Before', stepBefore],
                            ['After', stepAfter],
                          ] as const
                        ).map(([name, st]) =>
                          st ? (
                            <tr key={name}>
                              <th>{name}</th>
                              <td className="mono num">{withUnit(st.metrics.settling_s, 's')}</td>
                              <td className="mono num">{st.metrics.overshoot === null ? '—' : `${fmtNumber(st.metrics.overshoot * 100, 3)} %`}</td>
                              <td className="mono num">{withUnit(st.metrics.following_error_rms, st.unit)}</td>
                              <td className="small muted">{st.note ?? st.source ?? ''}</td>
                            </tr>
                          ) : null,
                        )}
                      </tbody>
                    </table>
                  </div>
                )}
                <h3 className="tuning-h3">Gains</h3>
                <GainTable lines={gainLines(result.gains)} compare testid="tuning-gains" />
                {result.notes && result.notes.length > 0 && (
                  <ul className="small muted tuning-notes">
                    {result.notes.map((n) => (
                      <li key={n}>{n}</li>
                    ))}
                  </ul>
                )}
                {undoNote && (
                  <div className="op-note" data-testid="tuning-undo-note">
                    {undoNote}
                  </div>
                )}
                <div className="op-row">
                  <button
                    type="button"
                    disabled={running || busy !== null || !info.undo.before || !writeOk}
                    title={gate.write ?? undefined}
                    onClick={() => setConfirm('undo-before')}
                    data-testid="tuning-undo-before"
                  >
                    Undo: gains before tuning
                  </button>
                  <button
                    type="button"
                    disabled={running || busy !== null || !info.undo.defaults || !writeOk}
                    title={gate.write ?? undefined}
                    onClick={() => setConfirm('undo-defaults')}
                    data-testid="tuning-undo-defaults"
                  >
                    Undo: default gains
                  </button>
                  <button type="button" className="primary" disabled={running || busy !== null || !writeOk} title={gate.write ?? undefined} onClick={() => setConfirm('store')} data-testid="tuning-store">
                    Store to EEPROM
                  </button>
                </div>
                <ControlNote sid={sid} what="Undo and Store to EEPROM are disabled" testid="tuning-result-control-note" rights={{ write: 'tune' }} />
              </div>
            )}
          </Step>
        </>
      )}

      <TuningHistory sid={sid} refresh={result?.job ?? ''} />

      {confirm && (
        <ConfirmDialog
          title={confirm === 'store' ? 'Store the parameters to EEPROM?' : confirm === 'undo-before' ? 'Return the gains to before tuning?' : 'Return the gains to their defaults?'}
          confirmLabel={confirm === 'store' ? 'Store to EEPROM' : 'Undo'}
          busy={busy !== null}
          onCancel={() => setConfirm(null)}
          onConfirm={() => void confirmed_(confirm)}
          testid="tuning-confirm-dialog"
        >
          {confirm === 'store' ? (
            <p>The drive saves all its parameters, the present gains included, to its non-volatile memory: they are used after the next power-on.</p>
          ) : (
            <p>
              {confirm === 'undo-before' ? 'The gains go back to the values before the last tuning.' : 'The gains go back to their default values.'}{' '}
              {info.undo.note}
            </p>
          )}
        </ConfirmDialog>
      )}
    </div>
  );
}
