/**
 * The note a page that changes a drive shows while this tab cannot: why (nobody holds
 * control, or who does; for servo on and motion also the dead-man link) and, when nobody
 * holds it, a Take control button right there. The page disables its write buttons with the
 * same sentence as their tooltip (useWriteGate), instead of sending and showing a 409.
 */
import { useState } from 'react';
import { type ControlView, energiseBlocked, writeBlocked } from '../lib/control';
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
}

export function useWriteGate(sid: string): WriteGate {
  const view = useControl(sid);
  return { view, write: writeBlocked(view), energise: energiseBlocked(view) };
}

export function ControlNote({
  sid,
  what,
  energise = false,
  testid = 'control-note',
}: {
  sid: string;
  /** What the page disables meanwhile, as a sentence: "Write, Save to EEPROM and Restore defaults are disabled". */
  what: string;
  /** The page also energises or moves the drive: say when the dead-man link is missing. */
  energise?: boolean;
  testid?: string;
}) {
  const gate = useWriteGate(sid);
  const [busy, setBusy] = useState(false);
  const v = gate.view;
  const why = energise ? gate.energise : gate.write;
  if (!why || !v.known) return null;

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
