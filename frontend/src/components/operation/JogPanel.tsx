/**
 * Jog: press and hold − or +. Pressing starts POST /motion/jog (profile velocity at the signed
 * velocity) and the dead-man heartbeat; releasing the button, the pointer leaving the page
 * (pointercancel, lost capture), the window losing focus or the tab being hidden sends a halt
 * and ends the heartbeat. If the page cannot send the halt, the missing heartbeat stops the
 * axis on the server within SERVODESK_DEADMAN_MS.
 */
import { useEffect, useRef, useState } from 'react';
import { operationApi } from '../../api/client';
import { byField, checkJog, defaultAcceleration, defaultVelocity, permissiveLimits } from '../../lib/motionLimits';
import { failureOf } from '../../lib/codes';
import { notifyError } from '../../state/notify';
import { Hint, LimitNote, ModeUnavailable, PanelFooter } from './common';
import type { PanelContext } from './context';
import { NumberField, useRawField } from './NumberField';
import { stopHeartbeat } from './operationStore';
import { useMotionRunner } from './useMotionRunner';

export function JogPanel({ ctx, modes }: { ctx: PanelContext; modes: readonly number[] }) {
  const limits = ctx.limits;
  const u = limits?.units ?? {};
  const v0 = defaultVelocity(limits);
  const [vel, setVel] = useRawField(v0);
  const [acc, setAcc] = useRawField(defaultAcceleration(limits, v0));
  const { run, failure, setFailure } = useMotionRunner(ctx.sid);
  const [dir, setDir] = useState<-1 | 0 | 1>(0);
  const holding = useRef(false);
  const sid = ctx.sid;

  const check = checkJog(
    { velocity: Math.abs(vel.raw ?? 0), acceleration: acc.raw ?? 0 },
    limits ?? permissiveLimits(modes),
  );
  const problems = byField(check);
  const missing = vel.raw === null || acc.raw === null || vel.error !== null || acc.error !== null;
  const list = [
    ...(missing ? ['enter a velocity and an acceleration'] : []),
    ...check.filter((p) => p.field !== 'mode').map((p) => `${p.field}: ${p.message}`),
  ];

  function release() {
    if (!holding.current) return;
    holding.current = false;
    setDir(0);
    stopHeartbeat(sid);
    operationApi.halt(sid).catch(notifyError);
  }

  async function press(d: -1 | 1) {
    if (holding.current) return;
    if (missing || check.length > 0) {
      setFailure(
        failureOf(new Error(list.join('; ') || 'the jog settings are not valid'), 'Jog (checked in the browser, nothing was sent)'),
      );
      return;
    }
    holding.current = true;
    setDir(d);
    const status = await run('Jog', () => operationApi.jog(sid, { velocity: d * Math.abs(vel.raw ?? 0), acceleration: acc.raw ?? 0 }));
    if (status === null) {
      // The start failed: nothing moves, the button is no longer "held".
      const releasedEarly = !holding.current;
      holding.current = false;
      setDir(0);
      // A release during the start makes the server refuse the start ("a halt came while the
      // motion was starting"): that is the person's own doing, not an error to show.
      if (releasedEarly) setFailure((f) => (f && /halt or stop came/i.test(f.message) ? null : f));
    }
  }

  // Leaving the window or hiding the tab is letting go of the button.
  useEffect(() => {
    const onBlur = () => release();
    const onVis = () => {
      if (document.visibilityState !== 'visible') release();
    };
    window.addEventListener('blur', onBlur);
    document.addEventListener('visibilitychange', onVis);
    return () => {
      window.removeEventListener('blur', onBlur);
      document.removeEventListener('visibilitychange', onVis);
      release();
    };
  }, [sid]);

  if (!modes.includes(3)) return <ModeUnavailable mode={3} modes={modes} what="Jog" testid="jog-unavailable" />;

  const button = (d: -1 | 1) => (
    <button
      type="button"
      className={`jog-btn${dir === d ? ' held' : ''}`}
      data-testid={d > 0 ? 'jog-plus' : 'jog-minus'}
      aria-pressed={dir === d}
      title={`Hold to jog in the ${d > 0 ? 'positive' : 'negative'} direction; let go to halt`}
      onPointerDown={(e) => {
        if (e.button !== 0) return;
        e.preventDefault();
        e.currentTarget.setPointerCapture(e.pointerId);
        void press(d);
      }}
      onPointerUp={release}
      onPointerCancel={release}
      onLostPointerCapture={release}
      onContextMenu={(e) => e.preventDefault()}
      onKeyDown={(e) => {
        if ((e.key === ' ' || e.key === 'Enter') && !e.repeat) {
          e.preventDefault();
          void press(d);
        }
      }}
      onKeyUp={(e) => {
        if (e.key === ' ' || e.key === 'Enter') release();
      }}
    >
      <span className="jog-sign">{d > 0 ? '+' : '−'}</span>
      <span className="jog-label">{d > 0 ? 'Jog positive' : 'Jog negative'}</span>
    </button>
  );

  return (
    <div className="op-panel" data-testid="panel-jog">
      <div className="op-fields">
        <NumberField
          testid="jog-velocity"
          label="Jog velocity (60FFh)"
          unit={u.velocity}
          entry={ctx.entry}
          field={vel}
          onChange={setVel}
          problem={problems.velocity}
          limit={<LimitNote limits={limits} name="max_velocity" unit={u.velocity} />}
        />
        <NumberField
          testid="jog-acceleration"
          label="Acceleration = deceleration (6083h, 6084h)"
          unit={u.acceleration}
          entry={ctx.entry}
          field={acc}
          onChange={setAcc}
          problem={problems.acceleration}
          limit={<LimitNote limits={limits} name="max_acceleration" unit={u.acceleration} signed={false} />}
        />
      </div>
      <div className="jog-row">
        {button(-1)}
        {button(1)}
        <div className="jog-state" data-testid="jog-state">
          {dir !== 0 ? (
            <span className="badge badge-warn">jogging {dir > 0 ? '+' : '−'} · heartbeat on</span>
          ) : (
            <span className="muted">released</span>
          )}
        </div>
      </div>
      <Hint>
        Hold a button to jog; the axis halts when you let go, move the pointer off, switch windows or hide the tab. The page
        sends a heartbeat every 50 ms while you hold it: if the heartbeats stop, the server halts and quick-stops the axis.
      </Hint>
      <PanelFooter problems={[]} failure={failure} testid="jog">
        {null}
      </PanelFooter>
    </div>
  );
}
