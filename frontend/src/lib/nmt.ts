/** What a session's NMT state (CiA 301 §7.3.2) rests on, for the pages' tooltips. */

/** The tooltip of an NMT state as the backend reports it ("preop", "operational", "stopped",
 * "bootup" or "unknown"), for a session on ``link`` (its link's registry name). */
export function nmtTitle(state: string | null | undefined, link?: string | null): string {
  if (link === 'cclink-ie-tsn') {
    return (
      'NMT state not read: a CC-Link IE TSN station changes it at its manager\'s command (003 §3-3), ' +
      'and servodesk reaches it by SLMP object access only.'
    );
  }
  if (link === 'profinet') {
    return (
      'No NMT on PROFINET: the drive\'s communication state belongs to its IO controller (004 §20.1.1); ' +
      'servodesk reaches it as an IO supervisor by record access only.'
    );
  }
  if (!state || state === 'unknown') {
    return (
      'NMT state unknown: no heartbeat from the drive has been seen and servodesk has sent no NMT ' +
      'command yet. A drive whose producer heartbeat time (1017h) is 0 sends none.'
    );
  }
  return `NMT state ${state}: from the drive's last heartbeat, or from the NMT command servodesk sent since (CiA 301 §7.3.2).`;
}

/** Whether a session on ``link`` has an NMT state to show: not over SLMP (the station's
 * manager owns it) or PROFINET (none; the IO controller owns the communication state). */
export function hasNmt(link: string | null | undefined): boolean {
  return link !== 'cclink-ie-tsn' && link !== 'profinet';
}

/** What a session's fieldbus tells about its communication state, for the pages (issue 48:
 * "unknown" for 4 of 5 drives said nothing). */
export interface NetworkState {
  /** What the state is: "NMT" (CANopen, CiA 301), "AL state" (EtherCAT, ETG.1000.6),
   * "AR" (PROFINET: servodesk's supervisor AR), "SLMP link" (CC-Link IE TSN). */
  label: string;
  /** The state itself, in words. */
  value: string;
  /** Where it comes from (tooltip). */
  title: string;
}

interface NetworkSession {
  link?: string | null;
  nmt_state: string | null;
  connected?: boolean;
}

export function networkState(s: NetworkSession): NetworkState {
  const up = s.connected !== false;
  if (s.link === 'profinet') {
    return {
      label: 'AR',
      // "operational": servodesk's IO controller AR runs the drive's telegram (cyclic data).
      value: !up
        ? 'down: the drive does not answer'
        : s.nmt_state === 'operational'
          ? "up (servodesk's supervisor AR and its IO AR: cyclic data)"
          : "up (servodesk's supervisor AR)",
      title: `${nmtTitle(s.nmt_state, s.link)} The AR shown is servodesk's own supervisor AR, up while the drive answers.`,
    };
  }
  if (s.link === 'cclink-ie-tsn') {
    return {
      label: 'SLMP link',
      value: up ? 'answering' : 'no answer',
      title: `${nmtTitle(s.nmt_state, s.link)} Shown instead: whether the station answers SLMP.`,
    };
  }
  if (s.link === 'ethercat') {
    const known = !!s.nmt_state && s.nmt_state !== 'unknown';
    return {
      label: 'AL state',
      value: known ? (s.nmt_state as string) : 'not read',
      title: "The slave's EtherCAT state machine (AL status 0130h, ETG.1000.6), read from the slave.",
    };
  }
  const unknown = !s.nmt_state || s.nmt_state === 'unknown';
  return {
    label: 'NMT',
    value: unknown ? 'not reported (no heartbeat)' : (s.nmt_state as string),
    title: nmtTitle(s.nmt_state, s.link),
  };
}
