/**
 * Profile position (mode 1): a relative or absolute move with target, profile velocity 6081h,
 * acceleration 6083h and deceleration 6084h. "Immediate" is controlword bit 5 (CiA 402-2
 * §6.5.1): on, a new target replaces the running one; off, it is queued behind it. The end
 * position of a relative move is checked against the software limits 607Dh before sending.
 */
import { useState } from 'react';
import { operationApi } from '../../api/client';
import type { MoveRequest } from '../../api/types';
import { byField, checkMove, defaultAcceleration, defaultVelocity, formatQuantity, permissiveLimits } from '../../lib/motionLimits';
import { Hint, LimitNote, ModeUnavailable, PanelFooter, PositionLimitNote } from './common';
import type { PanelContext } from './context';
import { NumberField, useRawField } from './NumberField';
import { useMotionRunner } from './useMotionRunner';

export function MovePanel({ ctx, modes }: { ctx: PanelContext; modes: readonly number[] }) {
  const limits = ctx.limits;
  const u = limits?.units ?? {};
  const v0 = defaultVelocity(limits);
  const [mode, setMode] = useState<MoveRequest['mode']>('relative');
  const [target, setTarget] = useRawField(null);
  const [vel, setVel] = useRawField(v0);
  const [acc, setAcc] = useRawField(defaultAcceleration(limits, v0));
  const [dec, setDec] = useRawField(defaultAcceleration(limits, v0));
  const [immediate, setImmediate] = useState(true);
  const { run, failure, busy } = useMotionRunner(ctx.sid);
  if (!modes.includes(1)) return <ModeUnavailable mode={1} modes={modes} what="A move (profile position)" testid="move-unavailable" />;

  const actual = ctx.state?.position ?? null;
  const req: MoveRequest = {
    mode,
    target: target.raw ?? 0,
    velocity: vel.raw,
    acceleration: acc.raw,
    deceleration: dec.raw,
    immediate,
  };
  const check = target.raw === null ? [] : checkMove(req, limits ?? permissiveLimits(modes), actual);
  const problems = byField(check);
  const parseErrors = [target, vel, acc, dec].some((f) => f.error !== null);
  const end = target.raw === null ? null : mode === 'relative' ? (actual === null ? null : actual + target.raw) : target.raw;

  return (
    <div className="op-panel" data-testid="panel-move">
      <div className="op-row">
        <div className="segmented" role="group" aria-label="Move kind">
          {(['relative', 'absolute'] as const).map((m) => (
            <button key={m} type="button" className={mode === m ? 'on' : ''} data-testid={`move-mode-${m}`} onClick={() => setMode(m)}>
              {m === 'relative' ? 'Relative' : 'Absolute'}
            </button>
          ))}
        </div>
        <label className="op-check">
          <input type="checkbox" checked={immediate} onChange={(e) => setImmediate(e.target.checked)} data-testid="move-immediate" />
          Change immediately (controlword bit 5)
        </label>
      </div>
      <div className="op-fields">
        <NumberField
          testid="move-target"
          label={mode === 'relative' ? 'Distance (607Ah, relative)' : 'Target position (607Ah)'}
          unit={u.position}
          entry={ctx.entry}
          field={target}
          onChange={setTarget}
          problem={problems.target}
          limit={<PositionLimitNote limits={limits} />}
        />
        <NumberField
          testid="move-velocity"
          label="Profile velocity (6081h)"
          unit={u.velocity}
          entry={ctx.entry}
          field={vel}
          onChange={setVel}
          problem={problems.velocity}
          optional
          limit={<LimitNote limits={limits} name="max_velocity" unit={u.velocity} signed={false} />}
        />
        <NumberField
          testid="move-acceleration"
          label="Acceleration (6083h)"
          unit={u.acceleration}
          entry={ctx.entry}
          field={acc}
          onChange={setAcc}
          problem={problems.acceleration}
          optional
          limit={<LimitNote limits={limits} name="max_acceleration" unit={u.acceleration} signed={false} />}
        />
        <NumberField
          testid="move-deceleration"
          label="Deceleration (6084h)"
          unit={u.acceleration}
          entry={ctx.entry}
          field={dec}
          onChange={setDec}
          problem={problems.deceleration}
          optional
          limit={<LimitNote limits={limits} name="max_deceleration" unit={u.acceleration} signed={false} />}
        />
      </div>
      <Hint>
        End position: <span className="mono" data-testid="move-end">{formatQuantity(end, u.position)}</span>
        {mode === 'relative' && ' (actual position + distance)'}. The page sends heartbeats until the drive reports the target
        reached.
      </Hint>
      <PanelFooter problems={check.filter((p) => p.field !== 'mode').map((p) => `${p.field}: ${p.message}`)} failure={failure} testid="move">
        <button
          type="button"
          className="go"
          data-testid="move-start"
          disabled={busy || target.raw === null || parseErrors || check.length > 0}
          onClick={() => void run('Move', () => operationApi.move(ctx.sid, req))}
        >
          {busy ? 'Starting…' : mode === 'relative' ? 'Move by distance' : 'Move to target'}
        </button>
      </PanelFooter>
    </div>
  );
}
