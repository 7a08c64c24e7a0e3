/**
 * Control and servo on/off on the Operation and Tuning pages. One client holds control of a
 * drive at a time; others watch (DESIGN.md). Take, Release and Force take are in the header's
 * control indicator (components/ControlIndicator), the same on every page; this card says who
 * holds control, whether this tab's WebSocket is bound as the dead-man, and switches the
 * servo on and off (POST /state enable / disable). Servo on needs control and the bound
 * dead-man link (docs/api.md "Control and motion as built"): without them the button is
 * disabled and the card says why.
 */
import { useState } from 'react';
import { api } from '../../api/client';
import type { DriveState } from '../../api/types';
import { applyState } from '../../state/store';
import { type Failure, failureOf } from '../../lib/codes';
import { FailureBox } from '../FailureBox';
import { StatePill } from '../StatePill';
import { useWriteGate } from '../ControlNote';
import { me } from './operationStore';

function since(t: number | null): string {
  if (t === null) return '';
  const d = new Date(t * 1000);
  return d.toLocaleTimeString();
}

export function ControlCard({ sid, state, socketOpen }: { sid: string; state: DriveState | null; socketOpen: boolean }) {
  const [busy, setBusy] = useState<string | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const gate = useWriteGate(sid);
  const control = gate.view;
  const owner = control.owner;
  const you = control.you;

  async function servo(command: 'enable' | 'disable') {
    setBusy(command);
    setFailure(null);
    try {
      applyState(sid, await api.command(sid, command, command === 'enable' ? 'Servo on' : 'Servo off'));
    } catch (e) {
      setFailure(failureOf(e, command));
    } finally {
      setBusy(null);
    }
  }

  const enabled = state?.state === 'Operation enabled';
  return (
    <section className="card" data-testid="control-card">
      <h2>
        Control <span className="h2-side muted">one client moves the drive; others watch · take it at the top right</span>
      </h2>
      <div className="control-row">
        <div className="control-owner" data-testid="control-owner" data-owner={owner ?? ''} data-you={you ? 'true' : 'false'}>
          {owner === null ? (
            <span className="muted">Nobody holds control: take it at the top right (Take control).</span>
          ) : you ? (
            <>
              <span className="badge badge-go">YOU</span> hold control <span className="mono muted">({owner})</span>{' '}
              <span className="muted">since {since(control.since)}</span>
            </>
          ) : (
            <>
              <span className="badge badge-warn">OTHER CLIENT</span> <span className="mono">{owner}</span> holds control{' '}
              <span className="muted">since {since(control.since)}</span>
              {control.orphaned ? <span className="muted"> (its tab closed; control lapses within 5 s)</span> : null}
            </>
          )}
        </div>
      </div>
      <div className="control-row">
        <div className="control-owner">
          <span className="muted">Servo</span> <StatePill state={state?.state ?? null} testid="servo-state" />
        </div>
        <div className="control-buttons">
          <button
            type="button"
            className="go"
            data-testid="servo-on"
            disabled={busy !== null || enabled || gate.energise !== null}
            title={gate.energise ?? 'walk the state machine to Operation enabled'}
            onClick={() => void servo('enable')}
          >
            {busy === 'enable' ? 'Servo on…' : 'Servo on'}
          </button>
          <button
            type="button"
            data-testid="servo-off"
            disabled={busy !== null || gate.write !== null}
            title={gate.write ?? 'disable the drive (Switch on disabled)'}
            onClick={() => void servo('disable')}
          >
            {busy === 'disable' ? 'Servo off…' : 'Servo off'}
          </button>
        </div>
      </div>
      {you && gate.energise && (
        <div className="op-note" data-testid="servo-blocked">
          Servo on is disabled: {gate.energise}.
        </div>
      )}
      <div className="muted small control-client" data-testid="client-id">
        This tab is client <span className="mono">{me()}</span> · dead-man link{' '}
        {!socketOpen ? (
          <strong className="bad-text">not connected</strong>
        ) : you ? (
          <span data-testid="control-card-deadman" data-state={control.bind.state}>
            {control.bind.state === 'bound'
              ? 'bound to your control (closing this tab stops the axis and disables the drive)'
              : control.bind.state === 'pending'
                ? 'binding…'
                : <strong className="bad-text">{`not bound${control.bind.message ? `: ${control.bind.message}` : ''}`}</strong>}
          </span>
        ) : (
          'connected (bound when this tab takes control)'
        )}
      </div>
      {control.protection && (
        <div className="muted small" data-testid="control-protection" title={`stop path: ${control.protection.stop_path}; the drive's own watchdog: ${control.protection.drive_watchdog ?? 'none armed'}`}>
          Protection: {control.protection.summary}
        </div>
      )}
      {failure && <FailureBox f={failure} testid="control-error" />}
    </section>
  );
}
