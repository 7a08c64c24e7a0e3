/**
 * The pure side of the All axes page (issue 48, "many axes at a glance"): which backup is a
 * drive's last one, how its alarm, its control and its protection read in one table cell.
 */
import type { BackupInfo, ControlProtection, DriveState, SessionInfo } from '../api/types';
import { sameDrive, toDate } from './backupHistory';

/**
 * The key the server gives a drive without a full identity (services/backup.py `drive_key`):
 * profile, interface, channel and node. A drive with vendor, product and serial is matched by
 * identity instead (lib/backupHistory `sameDrive`).
 */
export function placeKey(s: Pick<SessionInfo, 'profile_id' | 'interface' | 'channel' | 'node_id'>): string {
  return `${s.profile_id}@${s.interface}:${s.channel}:${s.node_id}`;
}

/** The newest backup of the session's drive, or null when it has none. */
export function lastBackup(session: Pick<SessionInfo, 'identity' | 'profile_id' | 'interface' | 'channel' | 'node_id'>, backups: readonly BackupInfo[]): BackupInfo | null {
  const place = placeKey(session);
  let best: BackupInfo | null = null;
  let bestT = -Infinity;
  for (const b of backups) {
    if (!(sameDrive(b.identity, session.identity) || b.drive_key === place)) continue;
    const t = toDate(b.time)?.getTime() ?? -Infinity;
    if (best === null || t > bestT) {
      best = b;
      bestT = t;
    }
  }
  return best;
}

/** "complete" or "incomplete · 3 unreadable" (a backup that lacks objects, issue 48). */
export function backupCompleteness(b: Pick<BackupInfo, 'complete' | 'unreadable'>): string {
  const n = b.unreadable?.length ?? 0;
  return b.complete !== false && n === 0 ? 'complete' : `incomplete · ${n} unreadable`;
}

/** The active alarm as one line (603Fh decoded by the profile), or null without one. */
export function alarmText(state: Pick<DriveState, 'error' | 'error_code'> | null): string | null {
  if (!state) return null;
  if (state.error) return `${state.error.display ?? state.error.code_hex} ${state.error.name}`;
  if (state.error_code) return `0x${state.error_code.toString(16).toUpperCase().padStart(4, '0')}`;
  return null;
}

export interface ControlCell {
  /** "you (this tab)", "you (another tab)", the holder's name, or "nobody". */
  text: string;
  /** STOP ALL of this user stops this axis (the user's account holds control). */
  stoppedByStopAll: boolean;
}

/**
 * Who holds control, for a person: this tab, another tab of the same account (STOP ALL stops
 * it too: control belongs to the account), another user or client, or nobody.
 */
export function controlCell(
  v: { owner: string | null; user: string | null; you: boolean },
  myUser: string | null,
): ControlCell {
  if (v.owner === null) return { text: 'nobody', stoppedByStopAll: false };
  const mine = v.you || (myUser !== null && v.user === myUser);
  if (v.you) return { text: 'you (this tab)', stoppedByStopAll: true };
  if (mine) return { text: `you (${v.owner})`, stoppedByStopAll: true };
  return { text: v.user && v.user !== 'local' ? `${v.user} (${v.owner})` : v.owner, stoppedByStopAll: false };
}

/** The protection in a few words: where the dead-man's stop goes out, the drive's watchdog. */
export function protectionText(p: ControlProtection | null): string {
  if (!p) return '—';
  return `${p.stop_path} · ${p.deadman_ms} ms${p.drive_watchdog ? ' · drive watchdog' : ' · no drive watchdog'}`;
}
