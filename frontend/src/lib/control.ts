/**
 * What the UI says and allows about control of a drive (docs/api.md "Control and motion as
 * built"): who holds it, whether this tab does, whether this tab's WebSocket is bound as the
 * drive's dead-man, and the sentence a disabled write button shows instead of a raw 409.
 *
 * Pure functions of the view, so the pages and the header agree and the rules are tested.
 */
import type { ControlProtection } from '../api/types';
import type { BindStatus } from '../ws/socket';

/** One session's control as this tab sees it. */
export interface ControlView {
  session: string;
  /** Read from the server (or pushed) at least once. */
  known: boolean;
  /** The holder's client label, or null. */
  owner: string | null;
  /** The account holding control (issue 45: control belongs to a user), or null. */
  user: string | null;
  since: number | null;
  /** Some WebSocket is bound to the holder's control (the server's view). */
  bound: boolean;
  /** The holder's socket closed: the drive was made safe; control lapses after 5 s. */
  orphaned: boolean;
  /** This tab holds control (its token is the holder's). */
  you: boolean;
  /** This tab's socket binding to the session: the dead-man of this tab. */
  bind: BindStatus;
  /** What stops the drive when its operator is lost (from the last GET / take), or null. */
  protection: ControlProtection | null;
}

export function emptyView(session: string, bind: BindStatus): ControlView {
  return { session, known: false, owner: null, user: null, since: null, bound: false, orphaned: false, you: false, bind, protection: null };
}

/**
 * Whether this tab holds control: the tab keeps the token for the session and the server
 * names this tab's label as the holder. (The label alone is no proof, the token alone may be
 * stale: both are needed; the server's own `you` corrects the token when they disagree.)
 */
export function holdsControl(known: boolean, owner: string | null, me: string, tokenHolds: boolean): boolean {
  return known && tokenHolds && owner !== null && owner === me;
}

/**
 * "user eve (client ui-3f2a…) holds control" as a person reads it; in the single-user mode
 * (everyone is "local") the client alone.
 */
export function holderText(owner: string, user: string | null = null): string {
  return user && user !== 'local' ? `user ${user} (client ${owner})` : `client ${owner}`;
}

/**
 * Why this tab may not change the drive now, or null when it may: the title of a disabled
 * write button and the line under it.
 */
export function writeBlocked(v: ControlView): string | null {
  if (v.you) return null;
  if (!v.known) return `reading who holds control of ${v.session}…`;
  if (v.owner === null) return `nobody holds control of ${v.session}: take control first (Take control, top right)`;
  const lapse = v.orphaned ? ' (its tab closed; control lapses within 5 s)' : '';
  return `${holderText(v.owner, v.user)} holds control of ${v.session}${lapse}: only the holder can change the drive; ask them to release it, or force-take it (top right)`;
}

/**
 * Why this tab may not energise or move the drive now (servo on, the controlword, motion,
 * homing, tuning), or null: control and this tab's WebSocket bound as the dead-man.
 */
export function energiseBlocked(v: ControlView): string | null {
  const w = writeBlocked(v);
  if (w) return w;
  switch (v.bind.state) {
    case 'bound':
      return null;
    case 'pending':
      return "binding this tab's dead-man link (its WebSocket) to the drive…";
    case 'refused':
      return `the server refused this tab's dead-man link: ${v.bind.message ?? 'no reason given'}`;
    default:
      return `this tab's dead-man link is not bound${v.bind.message ? `: ${v.bind.message}` : ''}`;
  }
}

/** The short state for the header: "you", the holder, or nobody; and the dead-man. */
export function deadmanText(v: ControlView): string {
  switch (v.bind.state) {
    case 'bound':
      return 'dead-man bound';
    case 'pending':
      return 'binding dead-man…';
    case 'refused':
      return 'dead-man refused';
    default:
      return 'dead-man NOT bound';
  }
}
