/**
 * Control ownership and servo on/off. One client holds control of a drive at a time; others
 * watch (DESIGN.md). Take is refused while someone else holds it; Force-take asks first and
 * names the client it takes control from, since their motion stops. Servo on / off walk the
 * state machine (POST /state enable / disable).
 */
import { useState } from 'react';
import { api, operationApi } from '../../api/client';
import type { Control, ControlAction, DriveState } from '../../api/types';
import { applyState } from '../../state/store';
import { type Failure, failureOf } from '../../lib/codes';
import { ConfirmDialog } from '../ConfirmDialog';
import { FailureBox } from '../FailureBox';
import { StatePill } from '../StatePill';
import { me, setControl } from './operationStore';

function since(t: number | null): string {
  if (t === null) return '';
  const d = new Date(t * 1000);
  return d.toLocaleTimeString();
}

export function ControlCard({ sid, control, state, socketOpen }: { sid: string; control: Control | null; state: DriveState | null; socketOpen: boolean }) {
  const [busy, setBusy] = useState<string | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [confirmForce, setConfirmForce] = useState(false);
  const owner = control?.owner ?? null;
  const you = owner !== null && owner === me();

  async function act(action: ControlAction, confirm = false) {
    setBusy(action);
    setFailure(null);
    try {
      setControl(sid, await operationApi.setControl(sid, action, confirm));
      setConfirmForce(false);
    } catch (e) {
      setFailure(failureOf(e, action));
    } finally {
      setBusy(null);
    }
  }

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
        Control <span className="h2-side muted">one client moves the drive; others watch</span>
      </h2>
      <div className="control-row">
        <div className="control-owner" data-testid="control-owner" data-owner={owner ?? ''} data-you={you ? 'true' : 'false'}>
          {owner === null ? (
            <span className="muted">Nobody holds control.</span>
          ) : you ? (
            <>
              <span className="badge badge-go">YOU</span> hold control <span className="mono muted">({owner})</span>{' '}
              <span className="muted">since {since(control?.since ?? null)}</span>
            </>
          ) : (
            <>
              <span className="badge badge-warn">OTHER CLIENT</span> <span className="mono">{owner}</span> holds control{' '}
              <span className="muted">since {since(control?.since ?? null)}</span>
            </>
          )}
        </div>
        <div className="control-buttons">
          {!you && (
            <button type="button" className="primary" data-testid="control-take" disabled={busy !== null} onClick={() => void act('take')}>
              Take control
            </button>
          )}
          {you && (
            <button type="button" data-testid="control-release" disabled={busy !== null} onClick={() => void act('release')}>
              Release control
            </button>
          )}
          {owner !== null && !you && (
            <button type="button" className="warn-btn" data-testid="control-force" disabled={busy !== null} onClick={() => setConfirmForce(true)}>
              Force-take…
            </button>
          )}
        </div>
      </div>
      <div className="control-row">
        <div className="control-owner">
          <span className="muted">Servo</span> <StatePill state={state?.state ?? null} testid="servo-state" />
        </div>
        <div className="control-buttons">
          <button type="button" className="go" data-testid="servo-on" disabled={busy !== null || enabled} onClick={() => void servo('enable')}>
            {busy === 'enable' ? 'Servo on…' : 'Servo on'}
          </button>
          <button type="button" data-testid="servo-off" disabled={busy !== null} onClick={() => void servo('disable')}>
            {busy === 'disable' ? 'Servo off…' : 'Servo off'}
          </button>
        </div>
      </div>
      <div className="muted small control-client" data-testid="client-id">
        This tab is client <span className="mono">{me()}</span> · dead-man link {socketOpen ? 'connected' : <strong className="bad-text">not connected</strong>}
      </div>
      {failure && <FailureBox f={failure} testid="control-error" />}
      {confirmForce && owner !== null && (
        <ConfirmDialog
          title="Take control from another client?"
          confirmLabel={`Take control from ${owner}`}
          busy={busy === 'force_take'}
          onCancel={() => setConfirmForce(false)}
          onConfirm={() => void act('force_take', true)}
          testid="force-dialog"
        >
          <p>
            Client <strong className="mono" data-testid="force-dialog-owner">{owner}</strong> holds control of {sid}
            {control?.since ? ` since ${since(control.since)}` : ''}. Taking it over stops the motion that client started, and
            its writes are refused from then on.
          </p>
          <p className="muted">Make sure nobody at the machine is relying on that client right now.</p>
        </ConfirmDialog>
      )}
    </section>
  );
}
