/**
 * HALT and QUICK STOP, big and always visible at the top of the Operation page (sticky while
 * scrolling, above every panel). Neither is ever disabled and neither asks anything: the
 * server never refuses them, from any client (docs/api.md). Halt is controlword bit 8 (the
 * axis stays enabled); quick stop is the CiA 402 quick stop (the drive leaves Operation
 * enabled). Both end this tab's heartbeat.
 */
import { operationApi } from '../../api/client';
import type { DriveState, MotionStatus } from '../../api/types';
import { modeName } from '../../lib/cia402';
import { formatEngineering } from '../../lib/format';
import { notify, notifyError } from '../../state/notify';
import { StatePill } from '../StatePill';
import type { HeartbeatInfo } from '../../lib/heartbeat';
import { setMotion, stopHeartbeat } from './operationStore';

export function StopBar({
  sid,
  state,
  motion,
  heartbeat,
}: {
  sid: string;
  state: DriveState | null;
  motion: MotionStatus | null;
  heartbeat: HeartbeatInfo;
}) {
  async function halt() {
    stopHeartbeat(sid);
    try {
      const m = await operationApi.halt(sid);
      setMotion(sid, m);
      if (m.state === 'idle' && m.message) notify({ kind: 'info', title: 'Halt', message: m.message, detail: null, hint: null });
    } catch (e) {
      notifyError(e);
    }
  }
  async function quickStop() {
    stopHeartbeat(sid);
    try {
      setMotion(sid, await operationApi.quickStop(sid));
    } catch (e) {
      notifyError(e);
    }
  }
  return (
    <div className="stop-bar" data-testid="stop-bar">
      <div className="stop-live">
        <span data-testid="op-state" className="drive-state">
          <StatePill state={state?.state ?? null} />
        </span>
        <span className="stop-val">
          <span className="muted">Position</span>{' '}
          <span className="mono" data-testid="op-position">{state?.position ?? '—'}</span>{' '}
          <span className="unit">{state?.position_raw_unit ?? ''}</span>
          <span className="mono muted"> {formatEngineering(state?.position_eng, state?.position_unit)}</span>
        </span>
        <span className="stop-val">
          <span className="muted">Velocity</span>{' '}
          <span className="mono" data-testid="op-velocity">{state?.velocity ?? '—'}</span>{' '}
          <span className="unit">{state?.velocity_raw_unit ?? ''}</span>
          <span className="mono muted"> {formatEngineering(state?.velocity_eng, state?.velocity_unit)}</span>
        </span>
        <span className="stop-val muted small" title="mode of operation display 6061h">
          {modeName(state?.mode, state?.mode_name)}
        </span>
        <span className="stop-val small" data-testid="motion-status" data-state={motion?.state ?? 'idle'} data-active={motion?.active ? 'true' : 'false'}>
          {motion?.active ? (
            <span className="badge badge-go">{motion.kind} running</span>
          ) : motion && motion.state !== 'idle' ? (
            <span className="badge badge-neutral">{motion.kind ?? 'motion'} {motion.state}</span>
          ) : null}{' '}
          <span className="muted">{motion?.message}</span>
        </span>
        {heartbeat.running && (
          <span className={`badge ${heartbeat.missed > 0 ? 'badge-bad' : 'badge-hb'}`} data-testid="heartbeat-indicator" title="dead-man heartbeat to the server every 50 ms">
            {heartbeat.missed > 0 ? `heartbeat NOT sent (${heartbeat.missed})` : 'heartbeat ♥'}
          </span>
        )}
      </div>
      <div className="stop-buttons">
        <button type="button" className="halt-btn" data-testid="halt" onClick={() => void halt()} title="Halt: controlword bit 8, the axis decelerates and stays enabled">
          HALT
        </button>
        <button type="button" className="qs-btn" data-testid="quick-stop" onClick={() => void quickStop()} title="Quick stop: the drive stops with its quick-stop ramp and leaves Operation enabled">
          QUICK STOP
        </button>
      </div>
    </div>
  );
}
