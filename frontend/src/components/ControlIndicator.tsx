/**
 * Who holds control of the drive in view, in the header of every session page, with Take /
 * Release / Force take (docs/api.md "Control and motion as built"): only the holder of
 * control changes a drive, so this is where a person takes it before a write, a restore, a
 * servo on or a jog, whatever page they are on. It also says whether this tab's WebSocket is
 * bound as the drive's dead-man (servo on and motion need it).
 *
 * Force take asks first and names the holder: taking control over stops that client's motion
 * and disables the drive.
 */
import { useState } from 'react';
import { createPortal } from 'react-dom';
import { tabClientId } from '../lib/backupClientId';
import { me, rightBlocked } from '../api/auth';
import { deadmanText, energiseBlocked, holderText } from '../lib/control';
import { useObservable } from '../state/observable';
import { forgetControl, releaseControl, takeControl, useControl } from '../state/control';
import { notifyError } from '../state/notify';
import { ConfirmDialog } from './ConfirmDialog';
import './control.css';

function since(t: number | null): string {
  return t === null ? '' : new Date(t * 1000).toLocaleTimeString();
}

export function ControlIndicator({ sid }: { sid: string }) {
  const v = useControl(sid);
  const [busy, setBusy] = useState<'take' | 'release' | 'force' | null>(null);
  const [confirmForce, setConfirmForce] = useState(false);
  const owner = v.owner;
  const bound = v.you && v.bind.state === 'bound';
  const who = useObservable(me);
  // Issue 45: control belongs to a user. A role without take_control only watches; taking it
  // over from another user needs force_control (administrators).
  const takeBlocked = rightBlocked('take_control');
  const otherUser = v.user !== null && who != null && v.user !== who.user;
  const forceBlocked = takeBlocked ?? (otherUser ? rightBlocked('force_control') : null);
  const holderName = owner === null ? null : v.user && v.user !== 'local' ? v.user : owner;

  async function act(what: 'take' | 'release' | 'force') {
    setBusy(what);
    try {
      if (what === 'release') await releaseControl(sid);
      else await takeControl(sid, what === 'force');
      setConfirmForce(false);
    } catch (e) {
      notifyError(e);
      if (what === 'release') forgetControl(sid);
    } finally {
      setBusy(null);
    }
  }

  const title = v.you
    ? `This tab (${tabClientId()}) holds control of ${sid} since ${since(v.since)}. ${energiseBlocked(v) ?? "Its WebSocket is the drive's dead-man: closing the tab stops the axis and disables the drive."}`
    : owner
      ? `${holderText(owner, v.user)} holds control of ${sid} since ${since(v.since)}${v.orphaned ? ' (its tab closed: the drive was made safe, control lapses within 5 s)' : ''}. Only the holder can change the drive.`
      : `Nobody holds control of ${sid}. Take control to change the drive (writes, servo on, motion).`;

  return (
    <div
      className={`ctl ${v.you ? 'ctl-you' : owner ? 'ctl-other' : 'ctl-none'}`}
      data-testid="control-indicator"
      data-session={sid}
      data-known={v.known ? 'true' : 'false'}
      data-owner={owner ?? ''}
      data-user={v.user ?? ''}
      data-you={v.you ? 'true' : 'false'}
      data-bound={bound ? 'true' : 'false'}
      data-orphaned={v.orphaned ? 'true' : 'false'}
      title={title}
    >
      <span className="ctl-label">Control</span>
      <span className="ctl-holder" data-testid="control-holder">
        {!v.known ? '…' : v.you ? 'you' : holderName ?? 'nobody'}
      </span>
      {v.you && (
        <span className={`ctl-dm ctl-dm-${v.bind.state}`} data-testid="control-deadman" data-state={v.bind.state}>
          {deadmanText(v)}
        </span>
      )}
      {!v.you && owner && v.orphaned && <span className="ctl-dm ctl-dm-refused">tab closed</span>}
      {v.known && !v.you && owner === null && (
        <button
          type="button"
          className="ctl-btn ctl-take"
          data-testid="control-take"
          disabled={busy !== null || takeBlocked !== null}
          title={takeBlocked ?? undefined}
          onClick={() => void act('take')}
        >
          {busy === 'take' ? 'Taking…' : 'Take control'}
        </button>
      )}
      {v.you && (
        <button type="button" className="ctl-btn" data-testid="control-release" disabled={busy !== null} onClick={() => void act('release')}>
          {busy === 'release' ? 'Releasing…' : 'Release'}
        </button>
      )}
      {v.known && !v.you && owner !== null && (
        <button
          type="button"
          className="ctl-btn ctl-force"
          data-testid="control-force"
          disabled={busy !== null || forceBlocked !== null}
          title={forceBlocked ?? undefined}
          onClick={() => setConfirmForce(true)}
        >
          Force take…
        </button>
      )}
      {confirmForce &&
        owner !== null &&
        createPortal(
        <ConfirmDialog
          title="Take control from another client?"
          confirmLabel={`Take control from ${owner}`}
          busy={busy === 'force'}
          onCancel={() => setConfirmForce(false)}
          onConfirm={() => void act('force')}
          testid="force-dialog"
        >
          <p>
            {v.user && v.user !== 'local' ? `User ${v.user}, client ` : 'Client '}
            <strong className="mono" data-testid="force-dialog-owner">{owner}</strong> holds control of {sid}
            {v.since ? ` since ${since(v.since)}` : ''}.
          </p>
          <p>
            Taking it over <strong>stops any motion that client started and disables the drive</strong> (Switch on disabled); its writes are
            refused from then on. Switch the servo on again yourself when the axis is safe to move.
          </p>
          <p className="muted">Make sure nobody at the machine is relying on that client right now.</p>
        </ConfirmDialog>,
          document.body,
        )}
    </div>
  );
}
