/**
 * Profile torque (mode 4): target torque 6071h (0.1 % of rated torque on CiA 402 drives) and
 * the torque slope 6087h. Runs until Halt or Quick stop, kept alive by the heartbeat.
 */
import { operationApi } from '../../api/client';
import type { UnitInfo } from '../../api/types';
import { byField, checkTorque, permissiveLimits } from '../../lib/motionLimits';
import { Hint, LimitNote, ModeUnavailable, PanelFooter } from './common';
import type { PanelContext } from './context';
import { NumberField, useRawField } from './NumberField';
import { useMotionRunner } from './useMotionRunner';

export function TorquePanel({ ctx, modes }: { ctx: PanelContext; modes: readonly number[] }) {
  const limits = ctx.limits;
  const tu = limits?.units.torque;
  const slopeUnit: UnitInfo | undefined = tu
    ? { raw_unit: `${tu.raw_unit ?? 'raw'}/s`, unit: tu.unit ? `${tu.unit}/s` : null, scale: tu.scale }
    : undefined;
  const [torque, setTorque] = useRawField(Math.min(100, limits?.max_torque ?? 100));
  const [slope, setSlope] = useRawField(1000);
  const { run, failure, busy } = useMotionRunner(ctx.sid);
  if (!modes.includes(4)) return <ModeUnavailable mode={4} modes={modes} what="Profile torque" testid="torque-unavailable" />;

  const req = { torque: torque.raw ?? 0, slope: slope.raw };
  const check = checkTorque(req, limits ?? permissiveLimits(modes));
  const problems = byField(check);
  const bad = torque.raw === null || [torque, slope].some((f) => f.error !== null) || check.length > 0;
  return (
    <div className="op-panel" data-testid="panel-torque">
      <div className="op-fields">
        <NumberField
          testid="tq-torque"
          label="Target torque (6071h, signed)"
          unit={tu}
          entry={ctx.entry}
          field={torque}
          onChange={setTorque}
          problem={problems.torque}
          limit={<LimitNote limits={limits} name="max_torque" unit={tu} />}
        />
        <NumberField
          testid="tq-slope"
          label="Torque slope (6087h)"
          unit={slopeUnit}
          entry={ctx.entry}
          field={slope}
          onChange={setSlope}
          problem={problems.slope}
          optional
        />
      </div>
      <Hint>An unloaded axis accelerates until it reaches its speed limit: keep the torque small and stop with HALT.</Hint>
      <PanelFooter problems={check.filter((p) => p.field !== 'mode').map((p) => `${p.field}: ${p.message}`)} failure={failure} testid="tq">
        <button
          type="button"
          className="go"
          data-testid="tq-start"
          disabled={busy || bad}
          onClick={() => void run('Profile torque', () => operationApi.torque(ctx.sid, req))}
        >
          {busy ? 'Starting…' : 'Apply torque'}
        </button>
      </PanelFooter>
    </div>
  );
}
