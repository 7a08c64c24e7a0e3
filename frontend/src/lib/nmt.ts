/** What a session's NMT state (CiA 301 §7.3.2) rests on, for the pages' tooltips. */

/** The tooltip of an NMT state as the backend reports it ("preop", "operational", "stopped",
 * "bootup" or "unknown"). */
export function nmtTitle(state: string | null | undefined): string {
  if (!state || state === 'unknown') {
    return (
      'NMT state unknown: no heartbeat from the drive has been seen and servodesk has sent no NMT ' +
      'command yet. A drive whose producer heartbeat time (1017h) is 0 sends none.'
    );
  }
  return `NMT state ${state}: from the drive's last heartbeat, or from the NMT command servodesk sent since (CiA 301 §7.3.2).`;
}
