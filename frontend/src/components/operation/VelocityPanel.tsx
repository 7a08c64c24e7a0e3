/**
 * Profile velocity (mode 3): target velocity 60FFh with acceleration 6083h and deceleration
 * 6084h. The axis turns until Halt or Quick stop; the page keeps it alive with heartbeats
 * while it is open, so closing the tab stops it.
 */
import { operationApi } from '../../api/client';
import { byField, checkVelocity, defaultAcceleration, defaultVelocity, permissiveLimits } from '../../lib/motionLimits';
import { Hint, LimitNote, ModeUnavailable, PanelFooter } from './common';
import type { PanelContext } from './context';
import { NumberField, useRawField } from './NumberField';
import { useMotionRunner } from './useMotionRunner';

export function VelocityPanel({ ctx, modes }: { ctx: PanelContext; modes: readonly number[] }) {
  const limits = ctx.limits;
  const u = limits?.units ?? {};
  const v0 = defaultVelocity(limits);
  const [vel, setVel] = useRawField(v0);
  const [acc, setAcc] = useRawField(defaultAcceleration(limits, v0));
  const [dec, setDec] = useRawField(defaultAcceleration(limits, v0));
  const { run, failure, busy } = useMotionRunner(ctx.sid);
  if (!modes.includes(3)) return <ModeUnavailable mode={3} modes={modes} what="Profile velocity" testid="velocity-unavailable" />;

  const req = { velocity: vel.raw ?? 0, acceleration: acc.raw, deceleration: dec.raw };
  const check = checkVelocity(req, limits ?? permissiveLimits(modes));
  const problems = byField(check);
  const bad = vel.raw === null || [vel, acc, dec].some((f) => f.error !== null) || check.length > 0;
  return (
    <div className="op-panel" data-testid="panel-velocity">
      <div className="op-fields">
        <NumberField
          testid="pv-velocity"
          label="Target velocity (60FFh, signed)"
          unit={u.velocity}
          entry={ctx.entry}
          field={vel}
          onChange={setVel}
          problem={problems.velocity}
          limit={<LimitNote limits={limits} name="max_velocity" unit={u.velocity} />}
        />
        <NumberField
          testid="pv-acceleration"
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
          testid="pv-deceleration"
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
      <Hint>The axis turns until you press HALT or QUICK STOP, leave this page or close the tab (the dead-man heartbeat ends).</Hint>
      <PanelFooter problems={check.filter((p) => p.field !== 'mode').map((p) => `${p.field}: ${p.message}`)} failure={failure} testid="pv">
        <button
          type="button"
          className="go"
          data-testid="pv-start"
          disabled={busy || bad}
          onClick={() => void run('Profile velocity', () => operationApi.velocity(ctx.sid, req))}
        >
          {busy ? 'Starting…' : 'Run at velocity'}
        </button>
      </PanelFooter>
    </div>
  );
}
