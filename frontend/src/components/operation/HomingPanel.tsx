/**
 * Homing (mode 6, CiA 402-2 §6.8): the family's documented methods (GET /homing/methods)
 * with what each does and which signals it uses, the parameters (6099h:01 switch-search
 * speed, 6099h:02 zero-search speed, 609Ah acceleration, 607Ch home offset; empty = keep the
 * drive's value), the estimate and time-out the next run gets (GET /homing/plan: maximum
 * travel and time-out can be set), start, and the run: elapsed time against the estimate and
 * the time-out, the phase statusword bits 13/12/10 tell, and how it ended. The end comes from
 * the run's last `homing` message and from the motion that carried it (operationStore), never
 * from the statusword alone: after a cancel the CTMM04x shows bits 13/12/10 = 000, "in
 * progress" (003 §4-4-7).
 */
import { useEffect, useState } from 'react';
import { operationApi } from '../../api/client';
import type { HomingMethod, HomingPlan, HomingRequest } from '../../api/types';
import { type Failure, failureOf } from '../../lib/codes';
import {
  HOMING_MODE,
  HOMING_STATE_TEXT,
  SW_HOMING_ATTAINED,
  SW_HOMING_ERROR,
  SW_TARGET_REACHED,
  decodeHoming,
  formatDuration,
  homingShown,
  parseTimeout,
  signalLabel,
} from '../../lib/homing';
import { byField, checkHoming } from '../../lib/motionLimits';
import { useObservable } from '../../state/observable';
import { FailureBox } from '../FailureBox';
import { Hint, ModeUnavailable, PanelFooter } from './common';
import type { PanelContext } from './context';
import { NumberField, useRawField } from './NumberField';
import { beginHeartbeat, operationLive, setHoming, startAnswered } from './operationStore';

export function HomingPanel({ ctx, modes }: { ctx: PanelContext; modes: readonly number[] }) {
  const sid = ctx.sid;
  const [methods, setMethods] = useState<HomingMethod[] | null>(null);
  const [loadFailure, setLoadFailure] = useState<Failure | null>(null);
  const [method, setMethod] = useState<number | null>(null);
  const [speedSwitch, setSpeedSwitch] = useRawField(null);
  const [speedZero, setSpeedZero] = useRawField(null);
  const [acc, setAcc] = useRawField(null);
  const [offset, setOffset] = useRawField(null);
  const [maxTravel, setMaxTravel] = useRawField(null);
  const [timeoutText, setTimeoutText] = useState('');
  const [plan, setPlan] = useState<HomingPlan | null>(null);
  const [planFailure, setPlanFailure] = useState<Failure | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [busy, setBusy] = useState(false);
  const [, setTick] = useState(0);
  const live = useObservable(operationLive(sid));
  const timeout = parseTimeout(timeoutText);
  const running = live.homing?.run?.active === true;

  // The estimate and time-out the next run would get, for what is entered now.
  useEffect(() => {
    if (method === null) return;
    let alive = true;
    const t = setTimeout(() => {
      operationApi
        .homingPlan(sid, {
          method,
          speed_switch: speedSwitch.raw,
          speed_zero: speedZero.raw,
          acceleration: acc.raw,
          max_travel: maxTravel.raw,
          timeout_s: timeout.value,
        })
        .then(
          (p) => {
            if (!alive) return;
            setPlan(p);
            setPlanFailure(null);
          },
          (e: unknown) => {
            if (!alive) return;
            setPlan(null);
            setPlanFailure(failureOf(e, 'Estimate the homing run'));
          },
        );
    }, 300);
    return () => {
      alive = false;
      clearTimeout(t);
    };
  }, [sid, method, speedSwitch.raw, speedZero.raw, acc.raw, maxTravel.raw, timeout.value]);

  // While a run lasts: count the elapsed time on between messages, and read the status now and
  // then in case a message was missed (the end is then read, not waited for).
  useEffect(() => {
    if (!running) return;
    const tick = setInterval(() => setTick((n) => n + 1), 1000);
    const poll = setInterval(() => {
      operationApi.homing(sid).then(
        (h) => setHoming(sid, h),
        () => undefined,
      );
    }, 2000);
    return () => {
      clearInterval(tick);
      clearInterval(poll);
    };
  }, [sid, running]);

  useEffect(() => {
    let alive = true;
    operationApi.homingMethods(sid).then(
      (m) => {
        if (!alive) return;
        setMethods(m);
        setMethod((cur) => cur ?? m[0]?.method ?? null);
      },
      (e: unknown) => alive && setLoadFailure(failureOf(e, 'Load the homing methods')),
    );
    operationApi.homing(sid).then(
      (h) => alive && setHoming(sid, h),
      () => undefined,
    );
    return () => {
      alive = false;
    };
  }, [sid]);

  if (!modes.includes(HOMING_MODE)) return <ModeUnavailable mode={HOMING_MODE} modes={modes} what="Homing" testid="homing-unavailable" />;
  if (loadFailure) return <FailureBox f={loadFailure} testid="homing-load-error" />;
  if (methods === null) return <div className="muted">Loading the homing methods…</div>;
  if (methods.length === 0) {
    return (
      <div className="op-unavailable" data-testid="homing-unavailable">
        This drive family documents no homing method, so homing cannot be started from here.
      </div>
    );
  }

  const u = ctx.limits?.units ?? {};
  const info = methods.find((m) => m.method === method) ?? null;
  const req: HomingRequest = {
    method: method ?? 0,
    speed_switch: speedSwitch.raw,
    speed_zero: speedZero.raw,
    acceleration: acc.raw,
    offset: offset.raw,
    max_travel: maxTravel.raw,
    timeout_s: timeout.value,
  };
  const check = checkHoming(
    req,
    methods.map((m) => m.method),
  );
  const problems = byField(check);
  const bad =
    method === null || [speedSwitch, speedZero, acc, offset, maxTravel].some((f) => f.error !== null) || timeout.error !== null || check.length > 0;

  const sw = ctx.state?.statusword ?? null;
  const decoded = sw === null ? null : decodeHoming(sw, ctx.state?.mode);
  const shown = homingShown(live.homing, decoded);
  const run = live.homing?.run ?? null;
  const elapsed = run ? run.elapsed_s + (run.active ? Math.max(0, performance.now() - live.homingAt) / 1000 : 0) : 0;
  const runMessage = run ? run.message || live.homing?.message || '' : (live.homing?.message ?? HOMING_STATE_TEXT[decoded ?? 'idle']);
  const bits = [
    { bit: 10, name: 'Target reached', mask: SW_TARGET_REACHED },
    { bit: 12, name: 'Homing attained', mask: SW_HOMING_ATTAINED },
    { bit: 13, name: 'Homing error', mask: SW_HOMING_ERROR },
  ];

  async function start() {
    setFailure(null);
    setBusy(true);
    // A run that moves the axis is under this tab's dead-man like a jog (docs/api.md): the
    // heartbeats begin before the request, and end with the motion GET /motion reports.
    beginHeartbeat(sid);
    try {
      setHoming(sid, await operationApi.startHoming(sid, req));
      startAnswered(sid, await operationApi.motion(sid));
    } catch (e) {
      startAnswered(sid, null);
      setFailure(failureOf(e, 'Start homing'));
    } finally {
      setBusy(false);
    }
  }

  return (
    <div className="op-panel" data-testid="panel-homing">
      <div className="op-row">
        <label className="op-field op-field-wide">
          <span className="op-field-label">Homing method (6098h)</span>
          <select value={method ?? ''} onChange={(e) => setMethod(Number(e.target.value))} data-testid="homing-method">
            {methods.map((m) => (
              <option key={m.method} value={m.method}>
                {m.method}: {m.name}
              </option>
            ))}
          </select>
        </label>
      </div>
      {info && (
        <div className="homing-info" data-testid="homing-info">
          <div>{info.description}</div>
          <div className="homing-signals">
            <span className="muted">Signals used:</span>{' '}
            {info.uses.length === 0 ? (
              <span className="chip">none (no motion to a switch)</span>
            ) : (
              info.uses.map((s) => (
                <span key={s} className="chip" data-testid={`homing-signal-${s}`}>
                  {signalLabel(s)}
                </span>
              ))
            )}
            {info.direction && <span className="muted"> · initial direction {info.direction}</span>}
            {info.needs_enable === false && <span className="muted"> · starts without servo on</span>}
            {info.equivalent != null && <span className="muted"> · simulated as CiA 402 method {info.equivalent}</span>}
          </div>
          {info.section && <div className="muted small">Manual: {info.section}</div>}
        </div>
      )}
      <div className="op-fields">
        <NumberField testid="homing-speed-switch" label="Switch-search speed (6099h:01)" unit={u.velocity} entry={ctx.entry} field={speedSwitch} onChange={setSpeedSwitch} problem={problems.speed_switch} optional />
        <NumberField testid="homing-speed-zero" label="Zero-search speed (6099h:02)" unit={u.velocity} entry={ctx.entry} field={speedZero} onChange={setSpeedZero} problem={problems.speed_zero} optional />
        <NumberField testid="homing-acceleration" label="Homing acceleration (609Ah)" unit={u.acceleration} entry={ctx.entry} field={acc} onChange={setAcc} problem={problems.acceleration} optional />
        <NumberField testid="homing-offset" label="Home offset (607Ch)" unit={u.position} entry={ctx.entry} field={offset} onChange={setOffset} problem={problems.offset} optional />
        <NumberField
          testid="homing-max-travel"
          label="Maximum travel"
          unit={u.position}
          entry={ctx.entry}
          field={maxTravel}
          onChange={setMaxTravel}
          problem={problems.max_travel}
          optional
          placeholder="software limits"
          title="The span the searches may cover, for the estimate (default: the software position limits 607Dh, or the twin's switches)"
        />
        <label className={`op-field${timeout.error ? ' op-field-bad' : ''}`}>
          <span className="op-field-label">
            Time-out<span className="muted"> (optional)</span>
          </span>
          <span className="op-input">
            <input
              type="text"
              inputMode="decimal"
              className="mono"
              data-testid="homing-timeout"
              value={timeoutText}
              placeholder={plan ? `${Math.round(plan.timeout_s)} (default)` : 'from the estimate'}
              aria-invalid={timeout.error ? true : undefined}
              onChange={(e) => setTimeoutText(e.target.value)}
            />
            <span className="op-unit mono">s</span>
          </span>
          <span className="op-limit muted">halt, then quick stop after it</span>
          {timeout.error && <span className="op-problem">{timeout.error}</span>}
        </label>
      </div>
      <div className="homing-plan" data-testid="homing-plan">
        {plan ? (
          <>
            <span>
              <span className="muted">Next run:</span>{' '}
              {plan.estimate_s !== null ? (
                <>
                  up to <strong data-testid="homing-plan-estimate">{formatDuration(plan.estimate_s)}</strong>
                </>
              ) : (
                <strong data-testid="homing-plan-estimate">no estimate</strong>
              )}
              {' · time-out '}
              <strong data-testid="homing-plan-timeout">{formatDuration(plan.timeout_s)}</strong>{' '}
              <span className="muted">({plan.timeout_source === 'user' ? 'yours' : plan.timeout_source === 'estimate' ? 'from the estimate' : 'default'})</span>
            </span>
            <span className="muted small">{plan.basis}</span>
            {plan.estimate?.assumptions.map((a) => (
              <span key={a} className="muted small">
                {a}
              </span>
            ))}
            {plan.warnings.map((w) => (
              <span key={w} className="homing-warning small" data-testid="homing-plan-warning">
                {w}
              </span>
            ))}
          </>
        ) : planFailure ? (
          <span className="muted small">No estimate: {planFailure.message}</span>
        ) : (
          <span className="muted small">Estimating…</span>
        )}
      </div>
      <div className="homing-status" data-testid="homing-status" data-state={shown.key}>
        <span className={`homing-state hs-${shown.key}`} data-testid="homing-state">
          {shown.label}
        </span>
        <span data-testid="homing-message">{runMessage}</span>
        <span className="homing-bits">
          {bits.map((b) => {
            const on = sw !== null && (sw & b.mask) !== 0;
            return (
              <span key={b.bit} className="homing-bit" title={`statusword bit ${b.bit}`}>
                <span className={`lamp${on ? ' lamp-on' : ''}`} /> {b.name} <span className="mono muted">(bit {b.bit})</span>
              </span>
            );
          })}
        </span>
        {ctx.state?.mode !== HOMING_MODE && <span className="muted small">(the drive is not in homing mode; bits read in mode {ctx.state?.mode ?? '—'})</span>}
      </div>
      {run && (
        <div className="homing-progress" data-testid="homing-progress" data-active={run.active ? 'true' : 'false'}>
          <span>
            Method {run.method}: <span data-testid="homing-elapsed">{formatDuration(elapsed)}</span>
            {run.estimate_s !== null ? ` of up to ${formatDuration(run.estimate_s)}` : ''}
            {' · time-out '}
            <span data-testid="homing-timeout-shown">{formatDuration(run.timeout_s)}</span>
            {run.phase && run.active ? <span className="muted"> · {run.phase} (bits 13/12/10)</span> : null}
          </span>
          <progress max={run.timeout_s} value={Math.min(elapsed, run.timeout_s)} title="elapsed time against the time-out" />
        </div>
      )}
      <Hint>
        Homing moves the axis: like a jog it runs under this tab&apos;s dead-man (keep this tab open and connected). A missed heartbeat, losing
        control or the time-out halts it and then quick-stops it; HALT and QUICK STOP above stop it at any time. Starting any method needs control
        and this tab&apos;s bound dead-man link; only a method that needs no servo on, started with the servo off, moves nothing and is not watched
        while it runs.
      </Hint>
      <PanelFooter problems={check.map((p) => `${p.field}: ${p.message}`)} failure={failure} testid="homing">
        <button type="button" className="go" data-testid="homing-start" disabled={busy || bad} onClick={() => void start()}>
          {busy ? 'Starting…' : 'Start homing'}
        </button>
      </PanelFooter>
    </div>
  );
}
