/**
 * The note a page that changes a drive shows while this tab cannot: why (nobody holds
 * control, or who does; for servo on and motion also the dead-man link) and, when nobody
 * holds it, a Take control button right there. The page disables its write buttons with the
 * same sentence as their tooltip (useWriteGate), instead of sending and showing a 409.
 */
import { useState } from 'react';
import { me, rightBlocked } from '../api/auth';
import { type ControlView, energiseBlocked, writeBlocked } from '../lib/control';
import { useObservable } from '../state/observable';
import { takeControl, useControl } from '../state/control';
import { notifyError } from '../state/notify';
import './control.css';

/** Whether this tab may change the drive now, and why not: for the page's buttons. */
export interface WriteGate {
  view: ControlView;
  /** Why writes are refused now (null: allowed). */
  write: string | null;
  /** Why servo on / motion are refused now (null: allowed). */
  energise: string | null;
  /** The refusal is the role's (it lacks the right), not control's. */
  byRole: { write: boolean; energise: boolean };
}

/**
 * The rights (docs/security.md "Roles") the page's writes and its servo on / motion need;
 * a role without them sees the buttons disabled with the reason, whoever holds control.
 */
export interface GateRights {
  write?: string;
  energise?: string;
}

export function useWriteGate(sid: string, rights: GateRights = {}): WriteGate {
  const view = useControl(sid);
  useObservable(me); // Re-render when the login (and so the rights) is known.
  const writeRole = rightBlocked(rights.write ?? 'take_control');
  const energiseRole = rightBlocked(rights.energise ?? 'jog_home');
  return {
    view,
    write: writeRole ?? writeBlocked(view),
    energise: energiseRole ?? energiseBlocked(view),
    byRole: { write: writeRole !== null, energise: energiseRole !== null },
  };
}

export function ControlNote({
  sid,
  what,
  energise = false,
  testid = 'control-note',
  rights = {},
}: {
  sid: string;
  /** What the page disables meanwhile, as a sentence: "Write, Save to EEPROM and Restore defaults are disabled". */
  what: string;
  /** The page also energises or moves the drive: say when the dead-man link is missing. */
  energise?: boolean;
  testid?: string;
  /** The rights the page's buttons need (useWriteGate). */
  rights?: GateRights;
}) {
  const gate = useWriteGate(sid, rights);
  const [busy, setBusy] = useState(false);
  const v = gate.view;
  const blocked = energise ? gate.energise : gate.write;
  if (!blocked || !v.known) return null;
  // The note has a Take control button of its own, to the right of this sentence: point there
  // rather than to the header's (issue 48: the sentence named a button that was elsewhere).
  const offersTake = !v.you && v.owner === null;
  const why = offersTake ? blocked.replace('(Take control, top right)', '(Take control, on the right)') : blocked;
  const byRole = energise ? gate.byRole.energise : gate.byRole.write;
  if (byRole) {
    return (
      <div className="control-note" role="note" data-testid={testid} data-reason="role">
        <span>
          <strong>Your role may not do this.</strong> {what}.{' '}
          <span data-testid={`${testid}-reason`}>{why.charAt(0).toUpperCase() + why.slice(1)}.</span>
        </span>
      </div>
    );
  }

  async function take() {
    setBusy(true);
    try {
      await takeControl(sid);
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(false);
    }
  }

  return (
    <div className="control-note" role="note" data-testid={testid} data-reason={v.you ? 'deadman' : v.owner ? 'other' : 'nobody'}>
      <span>
        <strong>{v.you ? "This tab's dead-man link is not bound." : 'This tab does not hold control.'}</strong> {what}.{' '}
        <span data-testid={`${testid}-reason`}>{why.charAt(0).toUpperCase() + why.slice(1)}{why.endsWith('…') ? '' : '.'}</span>
      </span>
      {!v.you && v.owner === null && (
        <button type="button" className="primary" data-testid={`${testid}-take`} disabled={busy} onClick={() => void take()}>
          {busy ? 'Taking…' : 'Take control'}
        </button>
      )}
    </div>
  );
}
