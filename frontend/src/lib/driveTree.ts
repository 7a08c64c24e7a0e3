/**
 * The pure side of the sidebar's drive tree (issue 48, "many axes at a glance"): the open
 * sessions grouped by bus, then by drive, then by axis, and how a drive's alarm and its
 * holder of control read in a row 200 px wide.
 *
 * Bus -> drive -> axis: a session is one axis (one CiA 402 state machine). Where a fieldbus
 * addresses several axes of one unit, the unit is the drive and its sessions are its axes:
 * a CC-Link IE TSN station reached by SLMP serves axes X..U behind one address (multidrop
 * no. = axis, CTMM04x manual 003 §4-2, docs/slmp.md), and a PROFINET device holds its drive
 * objects (DO-ID, PROFIdrive 004 §20.4.3.7, docs/profinet.md) behind one. On CANopen and
 * EtherCAT each node / slave is a drive of one axis (drive = axis): servodesk opens no
 * session per axis module of one node there.
 */
import type { DriveState, SessionInfo } from '../api/types';
import { alarmText, controlCell } from './axes';
import { nodeLabel } from './network';

export type TreeSession = Pick<SessionInfo, 'id' | 'fieldbus' | 'interface' | 'channel' | 'node_id' | 'identity' | 'profile_name' | 'state' | 'connected' | 'simulated'>;

/** The profiles' fieldbus ids as people call the fieldbus (as the status bar names them). */
const FIELDBUS_NAMES: Record<string, string> = {
  canopen: 'CANopen',
  ethercat: 'EtherCAT',
  'cclink-ie-tsn': 'CC-Link IE TSN',
  profinet: 'PROFINET',
};

/** Interfaces whose channel is one unit's address: their sessions are the axes of one drive. */
const STATION_INTERFACES = new Set(['slmp', 'profinet']);

export function fieldbusName(fieldbus: string): string {
  return FIELDBUS_NAMES[fieldbus] ?? fieldbus;
}

/** The bus a session is on, as servodesk keys it (the backend's LinkParams.bus_key). */
export function busKey(s: Pick<SessionInfo, 'interface' | 'channel'>): string {
  return `${s.interface}:${s.channel}`;
}

/**
 * "CANopen · virtual:sim0", "EtherCAT · eth1", "CC-Link IE TSN · SLMP 127.0.0.1:5010",
 * "PROFINET · 192.168.0.10": the interface is left out where the fieldbus implies it.
 */
export function busLabel(s: Pick<SessionInfo, 'fieldbus' | 'interface' | 'channel'>): string {
  const where =
    s.interface === 'slmp'
      ? `SLMP ${s.channel}`
      : s.interface === 'ethercat' || s.interface === 'profinet'
        ? s.channel
        : `${s.interface}:${s.channel}`;
  return `${fieldbusName(s.fieldbus)} · ${where}`;
}

/** The drive's name as the header shows it: the device's own name, else the profile's. */
export function driveName(s: Pick<SessionInfo, 'identity' | 'profile_name'>): string {
  return s.identity.device_name || s.profile_name;
}

export interface TreeAxis {
  session: TreeSession;
  /** "node 5", "slave 2", "axis X", "DO-ID 1" (lib/network nodeLabel, as the header). */
  label: string;
}

export interface TreeDrive {
  key: string;
  name: string;
  /** The node label of a one-axis drive; the station's address for a multi-axis one. */
  label: string;
  /** Sorted by node id; one entry: the drive is its axis. */
  axes: TreeAxis[];
}

export interface TreeBus {
  key: string;
  label: string;
  drives: TreeDrive[];
  /** Sessions of this bus in Fault (from the session list: a folded bus still says so). */
  faults: number;
}

const FAULT_STATES = new Set(['Fault', 'Fault reaction active']);

export function isFaultState(state: string | null | undefined): boolean {
  return state != null && FAULT_STATES.has(state);
}

function byNode(a: TreeAxis, b: TreeAxis): number {
  return a.session.node_id - b.session.node_id || a.session.id.localeCompare(b.session.id);
}

/**
 * The sessions as a tree: buses in the order of their first label (CANopen before EtherCAT
 * ...), drives by their lowest node id, axes by node id. Pure: the same list gives the same
 * tree, whatever order the server sent it in.
 */
export function driveTree(list: readonly TreeSession[]): TreeBus[] {
  const buses = new Map<string, { label: string; drives: Map<string, TreeAxis[]> }>();
  for (const s of list) {
    const bk = busKey(s);
    let bus = buses.get(bk);
    if (!bus) {
      bus = { label: busLabel(s), drives: new Map() };
      buses.set(bk, bus);
    }
    const dk = STATION_INTERFACES.has(s.interface) ? bk : `${bk}#${s.node_id}`;
    const axes = bus.drives.get(dk) ?? [];
    axes.push({ session: s, label: nodeLabel(s.interface, s.node_id) });
    bus.drives.set(dk, axes);
  }
  const out: TreeBus[] = [];
  for (const [key, bus] of buses) {
    const drives: TreeDrive[] = [];
    for (const [dk, axes] of bus.drives) {
      axes.sort(byNode);
      const first = axes[0] as TreeAxis;
      drives.push({
        key: dk,
        name: driveName(first.session),
        label: axes.length === 1 ? first.label : `${axes.length} axes`,
        axes,
      });
    }
    drives.sort((a, b) => byNode(a.axes[0] as TreeAxis, b.axes[0] as TreeAxis));
    const faults = drives.reduce((n, d) => n + d.axes.filter((a) => isFaultState(a.session.state)).length, 0);
    out.push({ key, label: bus.label, drives, faults });
  }
  out.sort((a, b) => a.label.localeCompare(b.label) || a.key.localeCompare(b.key));
  return out;
}

export interface TreeAlarm {
  /** The badge: the profile's display code or 603Fh in hex, or "FAULT" without a code. */
  text: string;
  /** The tooltip: the alarm's name and cause, or why the code is not shown. */
  title: string;
  /** 'fault' (red) or 'warning' (amber). */
  kind: 'fault' | 'warning';
  /** Read from the live state (it ages out when the page that subscribed closes). */
  live: boolean;
}

/**
 * A drive's alarm for its row. The live state (603Fh decoded by the profile) reaches the
 * browser only for drives a page subscribed to (the server reads the others at 1 Hz and says
 * only their CiA 402 state, in the `sessions` message), so it counts while it is `fresh` (a
 * subscribed drive's state arrives at least once a second) and agrees with the session list's
 * state; otherwise a drive in Fault is shown as FAULT and its code is on its Alarms page.
 */
export function treeAlarm(sessionState: string, live: Pick<DriveState, 'state' | 'error' | 'error_code'> | null, fresh: boolean): TreeAlarm | null {
  const current = live !== null && fresh && live.state === sessionState ? live : null;
  // A profile's "no error" entry (kind info, e.g. 603Fh = 0) is no alarm.
  const text = current?.error?.kind === 'info' ? null : alarmText(current);
  if (current && text !== null) {
    const code = current.error ? (current.error.display ?? current.error.code_hex) : text;
    const kind = isFaultState(current.state) || current.error?.kind === 'fault' ? 'fault' : 'warning';
    return { text: code, title: `${text}${current.error?.cause ? `: ${current.error.cause}` : ''}`, kind, live: true };
  }
  if (isFaultState(sessionState)) {
    return { text: 'FAULT', title: `${sessionState}: open the drive's Alarms page for the alarm code and its remedy`, kind: 'fault', live: false };
  }
  return null;
}

export interface TreeControl {
  /** "you", "you (ui-…)" (another tab of this user), the holder's name, "nobody", or "…" unread. */
  text: string;
  /** 'you' (this tab or this user: STOP ALL stops it), 'other', 'nobody', 'unknown'. */
  who: 'you' | 'other' | 'nobody' | 'unknown';
  title: string;
}

/** Who holds control, in the words of the header's indicator (components/ControlIndicator). */
export function treeControl(v: { known: boolean; owner: string | null; user: string | null; you: boolean }, myUser: string | null): TreeControl {
  if (!v.known) return { text: '…', who: 'unknown', title: 'reading who holds control' };
  const cell = controlCell(v, myUser);
  if (v.owner === null) return { text: 'nobody', who: 'nobody', title: 'Nobody holds control: take it in the header of the drive\u2019s page' };
  if (v.you) return { text: 'you', who: 'you', title: 'This tab holds control (STOP ALL and Esc stop this axis)' };
  if (cell.stoppedByStopAll) return { text: cell.text, who: 'you', title: `Another tab of yours (${v.owner}) holds control (STOP ALL stops this axis)` };
  return { text: cell.text, who: 'other', title: `${cell.text} holds control: only the holder can change the drive` };
}
