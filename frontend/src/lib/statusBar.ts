/**
 * The status bar's words and numbers (issue 48): one entry per bus from GET /status, with the
 * sessions' link state from the WebSocket laid over it (a lost link shows at once, not at the
 * next poll). A number the link cannot give is said to be not reported, never shown as 0.
 * And the store (issue 49): whether the central store answers, and what waits in the
 * gateway's local queue while it does not (docs/deployment.md).
 */
import type { BusStatus, SessionInfo, StoreStatus } from '../api/types';

export type BusState = BusStatus['state'];

/** Shown where a number is not known yet (no cycle, the status not loaded). */
export const UNKNOWN = '—';
export const NOT_REPORTED = 'not reported by this interface';

/** The link names of GET /status, as people call the fieldbus. */
const LINK_NAMES: Record<string, string> = {
  canopen: 'CANopen',
  ethercat: 'EtherCAT',
  'cclink-ie-tsn': 'CC-Link IE TSN',
  profinet: 'PROFINET',
};

export function busTitle(bus: BusStatus): string {
  const link = LINK_NAMES[bus.link] ?? bus.link;
  return `${link} ${bus.interface} ${bus.channel}`;
}

/**
 * The bus with its sessions' `connected` as the WebSocket last said (the `sessions` message the
 * server sends on every link lost or restored). An EtherCAT line's or a PROFINET IO AR's own
 * state (from its cycles) stays: it is newer than any poll of a session (over PROFINET the
 * supervisor AR still answers while the IO AR's link is lost).
 */
export function withLiveSessions(bus: BusStatus, live: readonly SessionInfo[] | null): BusStatus {
  if (!live) return bus;
  const byId = new Map(live.map((s) => [s.id, s]));
  // A session the list does not name yet (opened since) keeps the poll's word.
  const sessions = bus.sessions.map((s) => ({ ...s, connected: byId.get(s.id)?.connected ?? s.connected }));
  if (sessions.length === 0) return { ...bus, sessions };
  const cycles = bus.ethercat !== null || bus.profinet !== null;
  const lineState = cycles && bus.state !== 'up' && bus.state !== 'degraded';
  if (lineState) return { ...bus, sessions };
  const up = sessions.filter((s) => s.connected).length;
  const state: BusState = up === 0 ? 'down' : up === sessions.length ? 'up' : 'degraded';
  return { ...bus, sessions, state };
}

export function stateText(bus: BusStatus): string {
  const text: Record<BusState, string> = {
    up: 'link up',
    degraded: 'link degraded',
    down: 'link down',
    reconnecting: 'reconnecting',
  };
  const lost = bus.sessions.filter((s) => !s.connected).map((s) => `node ${s.node_id}`);
  const which = bus.state === 'degraded' && lost.length ? ` (${lost.join(', ')} not answering)` : '';
  return `${text[bus.state]}${which}`;
}

function number(value: number, digits: number): string {
  return value.toLocaleString('en-US', { maximumFractionDigits: digits });
}

/** Frames per second and the load where the link measures them; a PROFINET IO AR's frames. */
export function trafficText(bus: BusStatus): string {
  const io = bus.profinet;
  if (io) return `${number(io.output_frames, 0)} frames sent, ${number(io.input_frames, 0)} received`;
  const t = bus.traffic;
  if (!t) return `load ${NOT_REPORTED}`;
  const frames = `${number(t.frames_per_s, 1)} frames/s`;
  return t.load_percent === null ? `${frames}, load ${UNKNOWN}` : `${frames}, load ${number(t.load_percent, 1)} %`;
}

/** The error counters as the link reports them. */
export function errorsText(bus: BusStatus): string {
  const parts = [`${bus.failed_requests} of ${bus.requests} requests failed`];
  if (bus.ethercat) {
    parts.push(`${bus.ethercat.wkc_errors} WKC errors`, `${bus.ethercat.missing_frames} missing frames`);
  }
  if (bus.profinet) {
    parts.push(`${bus.profinet.lost} frames lost`, `${bus.profinet.data_status_errors} data-status errors`);
    if (bus.profinet.losses) parts.push(`link lost ${bus.profinet.losses}×`);
  }
  const t = bus.traffic;
  if (t) {
    if (t.error_frames === null && t.bus_state === null) {
      parts.push(`error frames and controller state ${NOT_REPORTED}`);
    } else {
      parts.push(t.error_frames === null ? `error frames ${NOT_REPORTED}` : `${t.error_frames} error frames`);
      parts.push(t.bus_state === null ? `controller state ${NOT_REPORTED}` : `error ${t.bus_state}`);
    }
  }
  return parts.join(', ');
}

/** The cycle: what was set and what the producer measured, in ms. */
export function cycleText(bus: BusStatus): string {
  const c = bus.cycle;
  if (!c && bus.profinet) return `cycle ${number(bus.profinet.cycle_ms, 3)} ms set, ${UNKNOWN} measured`;
  if (!c) return `cycle ${UNKNOWN}`;
  const measured = c.measured_ms === null ? UNKNOWN : `${number(c.measured_ms, 3)} ms`;
  const dc = c.sync === 'dc' ? ' DC' : '';
  return `cycle${dc} ${number(c.configured_ms, 3)} ms set, ${measured} measured`;
}

/** The sentence announced to a screen reader when a bus's state changes (and only then). */
export function stateChanges(before: readonly BusStatus[], after: readonly BusStatus[]): string {
  const old = new Map(before.map((b) => [busTitle(b), b.state]));
  return after
    .filter((b) => old.has(busTitle(b)) && old.get(busTitle(b)) !== b.state)
    .map((b) => `${busTitle(b)}: ${stateText(b)}`)
    .join('. ');
}

/** Records waiting in the gateway's local queue, all kinds together. */
export function queuedCount(store: StoreStatus): number {
  return Object.values(store.queued).reduce((sum, n) => sum + n, 0);
}

/** The store's dot: down while unreachable, degraded while its queue drains, else up. */
export function storeState(store: StoreStatus): BusState {
  if (!store.reachable) return 'down';
  return queuedCount(store) > 0 ? 'degraded' : 'up';
}

function records(n: number): string {
  return `${n} record${n === 1 ? '' : 's'}`;
}

/** Local wall-clock time of an epoch in seconds, as the operator's clock shows it (12:03). */
export function clockText(epochS: number): string {
  const d = new Date(epochS * 1000);
  return `${String(d.getHours()).padStart(2, '0')}:${String(d.getMinutes()).padStart(2, '0')}`;
}

/**
 * One line: "store: PostgreSQL ok", "store: unreachable since 12:03, 14 records queued
 * locally", "store: PostgreSQL ok, syncing 3 records"; a SQLite store is the local file.
 */
export function storeText(store: StoreStatus): string {
  if (store.engine === 'sqlite') return 'store: SQLite (local file)';
  const n = queuedCount(store);
  if (!store.reachable) {
    const since = store.since === null ? '' : ` since ${clockText(store.since)}`;
    return `store: unreachable${since}, ${records(n)} queued locally`;
  }
  return n > 0 ? `store: PostgreSQL ok, syncing ${records(n)}` : 'store: PostgreSQL ok';
}

/** The store's tooltip: where it is, the last error and the last sync. */
export function storeTitle(store: StoreStatus): string {
  const lines = [store.url];
  if (store.last_error) lines.push(`last error: ${store.last_error}`);
  if (store.last_sync !== null) lines.push(`last sync: ${clockText(store.last_sync)} (${records(store.synced)} since start)`);
  const kinds = Object.entries(store.queued).filter(([, v]) => v > 0);
  if (kinds.length) lines.push(`queued: ${kinds.map(([k, v]) => `${v} ${k.replace('_', ' ')}`).join(', ')}`);
  return lines.join('\n');
}
