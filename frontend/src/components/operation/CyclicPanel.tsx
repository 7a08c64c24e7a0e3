/**
 * Cyclic synchronous modes (csp 8, csv 9, cst 10): the backend's set-point generator writes a
 * sine or triangle ("ramp") around the start (csp) or around 0 (csv, cst) every 10 ms for the
 * duration, rounded up to whole periods. Only where the family lists the mode; otherwise the
 * panel says why not (e.g. the generic CiA 402 profile and smartris have none).
 */
import { useState } from 'react';
import { operationApi } from '../../api/client';
import type { CyclicMode, CyclicRequest } from '../../api/types';
import { MODE_NAMES } from '../../lib/cia402';
import { CYCLIC_MODE_NUMBER, byField, checkCyclic, cyclicUnavailable, formatNumber, permissiveLimits, waveformSlope } from '../../lib/motionLimits';
import { Hint, LimitNote, PanelFooter, PositionLimitNote } from './common';
import type { PanelContext } from './context';
import { NumberField, useRawField } from './NumberField';
import { useMotionRunner } from './useMotionRunner';

const MODES: readonly CyclicMode[] = ['csp', 'csv', 'cst'];

export function CyclicPanel({ ctx, modes }: { ctx: PanelContext; modes: readonly number[] }) {
  const limits = ctx.limits;
  const eff = limits ?? permissiveLimits(modes);
  const available = MODES.filter((m) => cyclicUnavailable(eff, m) === null);
  const [mode, setMode] = useState<CyclicMode>(available[0] ?? 'csp');
  const [waveform, setWaveform] = useState<CyclicRequest['waveform']>('sine');
  const [amp, setAmp] = useRawField(null);
  const [freqText, setFreqText] = useState('0.5');
  const [durText, setDurText] = useState('4');
  const { run, failure, busy } = useMotionRunner(ctx.sid);

  if (available.length === 0) {
    const have = modes.map((m) => MODE_NAMES[m] ?? `mode ${m}`).join(', ') || 'none listed';
    return (
      <div className="op-unavailable" data-testid="cyclic-unavailable">
        <strong>Cyclic synchronous modes are not available on this drive.</strong> csp, csv and cst (6060h = 8, 9, 10) are not
        among this family's documented modes of operation, so the backend's set-point generator has nothing to drive. The
        family has: {have}. Use the profile modes (Move, Velocity, Torque) instead.
      </div>
    );
  }

  const u = limits?.units ?? {};
  const unit = mode === 'csp' ? u.position : mode === 'csv' ? u.velocity : u.torque;
  const frequency = Number(freqText);
  const duration = Number(durText);
  const req: CyclicRequest = { mode, waveform, amplitude: amp.raw ?? 0, frequency, duration };
  const check = checkCyclic(req, eff, ctx.state?.position ?? null);
  const problems = byField(check);
  const bad = amp.raw === null || amp.error !== null || check.length > 0;
  const periods = frequency > 0 ? Math.max(1, Math.ceil(duration * frequency - 1e-9)) : 0;
  const peak = frequency > 0 && amp.raw !== null ? amp.raw * waveformSlope(waveform, frequency) : null;

  return (
    <div className="op-panel" data-testid="panel-cyclic">
      <div className="op-row">
        <div className="segmented" role="group" aria-label="Cyclic mode">
          {MODES.map((m) => {
            const why = cyclicUnavailable(eff, m);
            return (
              <button
                key={m}
                type="button"
                className={mode === m ? 'on' : ''}
                disabled={why !== null}
                title={why ?? MODE_NAMES[CYCLIC_MODE_NUMBER[m]]}
                data-testid={`cyclic-mode-${m}`}
                onClick={() => setMode(m)}
              >
                {m}
              </button>
            );
          })}
        </div>
        <div className="segmented" role="group" aria-label="Waveform">
          {(['sine', 'ramp'] as const).map((w) => (
            <button key={w} type="button" className={waveform === w ? 'on' : ''} onClick={() => setWaveform(w)}>
              {w === 'sine' ? 'Sine' : 'Triangle (ramp)'}
            </button>
          ))}
        </div>
      </div>
      {MODES.filter((m) => !available.includes(m)).map((m) => (
        <div key={m} className="muted small">
          {m}: {cyclicUnavailable(eff, m)}.
        </div>
      ))}
      <div className="op-fields">
        <NumberField
          testid="cyclic-amplitude"
          label={`Amplitude (${mode === 'csp' ? 'around the start position' : 'around 0'})`}
          unit={unit}
          entry={ctx.entry}
          field={amp}
          onChange={setAmp}
          problem={problems.amplitude}
          limit={
            mode === 'csp' ? (
              <PositionLimitNote limits={limits} />
            ) : mode === 'csv' ? (
              <LimitNote limits={limits} name="max_velocity" unit={u.velocity} />
            ) : (
              <LimitNote limits={limits} name="max_torque" unit={u.torque} />
            )
          }
        />
        <label className={`op-field${problems.frequency ? ' op-field-bad' : ''}`}>
          <span className="op-field-label">Frequency</span>
          <span className="op-input">
            <input className="mono" value={freqText} onChange={(e) => setFreqText(e.target.value)} data-testid="cyclic-frequency" />
            <span className="op-unit mono">Hz</span>
          </span>
          <span className="op-limit muted">0 &lt; f ≤ 10 Hz (set-points every 10 ms)</span>
          {problems.frequency && <span className="op-problem">{problems.frequency}</span>}
        </label>
        <label className={`op-field${problems.duration ? ' op-field-bad' : ''}`}>
          <span className="op-field-label">Duration</span>
          <span className="op-input">
            <input className="mono" value={durText} onChange={(e) => setDurText(e.target.value)} data-testid="cyclic-duration" />
            <span className="op-unit mono">s</span>
          </span>
          <span className="op-limit muted">
            {periods > 0 ? `${periods} whole period${periods === 1 ? '' : 's'} = ${formatNumber(periods / frequency)} s` : '≤ 60 s'}
          </span>
          {problems.duration && <span className="op-problem">{problems.duration}</span>}
        </label>
      </div>
      {peak !== null && mode !== 'cst' && (
        <Hint>
          Peak {mode === 'csp' ? 'velocity' : 'acceleration'} of the waveform: {formatNumber(peak)}{' '}
          {mode === 'csp' ? (u.velocity?.raw_unit ?? '') : (u.acceleration?.raw_unit ?? '')}
        </Hint>
      )}
      <PanelFooter problems={check.filter((p) => p.field !== 'mode').map((p) => `${p.field}: ${p.message}`)} failure={failure} testid="cyclic">
        <button
          type="button"
          className="go"
          data-testid="cyclic-start"
          disabled={busy || bad}
          onClick={() => void run(`Cyclic ${mode}`, () => operationApi.cyclic(ctx.sid, req))}
        >
          {busy ? 'Starting…' : `Run ${mode} ${waveform}`}
        </button>
      </PanelFooter>
    </div>
  );
}
