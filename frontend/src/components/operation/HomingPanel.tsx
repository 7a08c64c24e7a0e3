/**
 * Homing (mode 6, CiA 402-2 §6.8): the family's documented methods (GET /homing/methods)
 * with what each does and which signals it uses, the parameters (6099h:01 switch-search
 * speed, 6099h:02 zero-search speed, 609Ah acceleration, 607Ch home offset; empty = keep the
 * drive's value), start, and the run's state decoded from statusword bits 13/12/10.
 */
import { useEffect, useState } from 'react';
import { operationApi } from '../../api/client';
import type { HomingMethod, HomingRequest } from '../../api/types';
import { type Failure, failureOf } from '../../lib/codes';
import { HOMING_MODE, HOMING_STATE_TEXT, SW_HOMING_ATTAINED, SW_HOMING_ERROR, SW_TARGET_REACHED, decodeHoming, signalLabel } from '../../lib/homing';
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
  const [failure, setFailure] = useState<Failure | null>(null);
  const [busy, setBusy] = useState(false);
  const live = useObservable(operationLive(sid));

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
  };
  const check = checkHoming(
    req,
    methods.map((m) => m.method),
  );
  const problems = byField(check);
  const bad = method === null || [speedSwitch, speedZero, acc, offset].some((f) => f.error !== null) || check.length > 0;

  const sw = ctx.state?.statusword ?? null;
  const decoded = sw === null ? null : decodeHoming(sw, ctx.state?.mode);
  const runState = live.homing?.state ?? decoded ?? 'idle';
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
      </div>
      <div className="homing-status" data-testid="homing-status" data-state={runState}>
        <span className={`homing-state hs-${runState}`} data-testid="homing-state">
          {runState}
        </span>
        <span>{live.homing?.message ?? HOMING_STATE_TEXT[runState]}</span>
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
      <Hint>Homing does not need the dead-man heartbeat: HALT and QUICK STOP above stop it.</Hint>
      <PanelFooter problems={check.map((p) => `${p.field}: ${p.message}`)} failure={failure} testid="homing">
        <button type="button" className="go" data-testid="homing-start" disabled={busy || bad} onClick={() => void start()}>
          {busy ? 'Starting…' : 'Start homing'}
        </button>
      </PanelFooter>
    </div>
  );
}
