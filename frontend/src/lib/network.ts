/**
 * The pure parts of the Network configuration page (and of the Connect page's SLMP axis): the
 * axis of a CC-Link IE TSN station reached by SLMP, the profile's network objects joined with
 * its object list, and its LED states grouped per LED.
 */
import type { NetworkLedInfo, NetworkObjectInfo, ObjectInfo, ProfileDetail } from '../api/types';
import { canonicalAddress, isReadable } from './dictionary';

/** 003 §4-2: the SLMP 4E frame's multidrop station no. 0..3 addresses axis X, Y, Z, U; a
 * session's node id is the axis + 1 (docs/slmp.md). */
export const SLMP_AXES = ['X', 'Y', 'Z', 'U'] as const;
export type SlmpAxis = (typeof SLMP_AXES)[number];

/** The axis letter of an SLMP session's node id (1 = X ... 4 = U), or null for another. */
export function slmpAxis(nodeId: number): SlmpAxis | null {
  return Number.isInteger(nodeId) ? (SLMP_AXES[nodeId - 1] ?? null) : null;
}

/** "X (node id 1, multidrop 0)": how the pages name an SLMP axis. */
export function slmpAxisLabel(nodeId: number): string {
  const axis = slmpAxis(nodeId);
  return axis ? `${axis} (node id ${nodeId}, multidrop ${nodeId - 1})` : `no axis (node id ${nodeId})`;
}

/** How a session's node is named on its fieldbus: "axis X" (SLMP), "DO-ID 1" (PROFINET, the
 * drive object), "slave 1" (EtherCAT, position + 1), else "node 5" (CANopen). */
export function nodeLabel(iface: string, nodeId: number): string {
  if (iface === 'slmp') return `axis ${slmpAxis(nodeId) ?? `? (node id ${nodeId})`}`;
  if (iface === 'profinet') return `DO-ID ${nodeId}`;
  if (iface === 'ethercat') return `slave ${nodeId}`;
  return `node ${nodeId}`;
}

/** One object of the profile's network section with the profile's entry for it (null: the
 * profile does not list it, which the backend's check_profile refuses; kept for an old one). */
export interface NetworkRow {
  entry: NetworkObjectInfo;
  object: ObjectInfo | null;
}

export function networkRows(profile: Pick<ProfileDetail, 'object_list' | 'network'>): NetworkRow[] {
  const entries = profile.network?.objects ?? [];
  if (!entries.length) return [];
  const byAddress = new Map(profile.object_list.map((o) => [canonicalAddress(o.address), o] as const));
  return entries.map((entry) => ({ entry, object: byAddress.get(canonicalAddress(entry.address)) ?? null }));
}

/** The addresses the page reads: the rows' objects the drive can be asked for. */
export function networkAddresses(rows: readonly NetworkRow[]): string[] {
  return rows.filter((r) => r.object !== null && isReadable(r.object)).map((r) => canonicalAddress(r.entry.address));
}

export interface LedGroup {
  led: string;
  states: NetworkLedInfo[];
}

/** The LED states per LED, LEDs in the order the profile first names them (one LED's states
 * stay together in the panel even where the profile lists them apart). */
export function ledGroups(leds: readonly NetworkLedInfo[]): LedGroup[] {
  const out: LedGroup[] = [];
  const by = new Map<string, LedGroup>();
  for (const l of leds) {
    let g = by.get(l.led);
    if (!g) {
      g = { led: l.led, states: [] };
      by.set(l.led, g);
      out.push(g);
    }
    g.states.push(l);
  }
  return out;
}
