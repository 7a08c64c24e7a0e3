import { describe, expect, it } from 'vitest';
import type { BusStatus, SessionInfo, StoreStatus } from '../api/types';
import {
  NOT_REPORTED,
  cycleText,
  errorsText,
  queuedCount,
  stateChanges,
  stateText,
  storeState,
  storeText,
  storeTitle,
  trafficText,
  withLiveSessions,
} from './statusBar';

function virtualBus(over: Partial<BusStatus> = {}): BusStatus {
  return {
    link: 'canopen',
    interface: 'virtual',
    channel: 'servodesk-sim',
    bitrate: null,
    state: 'up',
    reason: null,
    sessions: [
      { id: 'a-1', node_id: 1, connected: true },
      { id: 'b-2', node_id: 2, connected: true },
    ],
    requests: 120,
    failed_requests: 2,
    traffic: {
      frames_per_s: 14,
      load_percent: null,
      load_basis: 'no load: the bus was opened without a bitrate',
      error_frames: null,
      bus_state: null,
    },
    cycle: null,
    ethercat: null,
    profinet: null,
    ...over,
  };
}

const live = (connected: Record<string, boolean>) =>
  Object.entries(connected).map(([id, c]) => ({ id, connected: c }) as SessionInfo);

describe('status bar text', () => {
  it('says what the virtual bus cannot report instead of showing zeros', () => {
    const bus = virtualBus();
    expect(trafficText(bus)).toBe('14 frames/s, load —');
    expect(errorsText(bus)).toBe(
      `2 of 120 requests failed, error frames and controller state ${NOT_REPORTED}`,
    );
    expect(cycleText(bus)).toBe('cycle —');
  });

  it('shows the load, the counters and the cycle with their units where measured', () => {
    const bus = virtualBus({
      bitrate: 500_000,
      traffic: { frames_per_s: 812.4, load_percent: 17.96, load_basis: '', error_frames: 3, bus_state: 'passive' },
      cycle: { session: 'a-1', sync: 'dc', configured_ms: 1, measured_ms: 1.0004, cycles: 1000 },
    });
    expect(trafficText(bus)).toBe('812.4 frames/s, load 18 %');
    expect(errorsText(bus)).toBe('2 of 120 requests failed, 3 error frames, error passive');
    expect(cycleText(bus)).toBe('cycle DC 1 ms set, 1 ms measured');
  });

  it('names the EtherCAT line counters and a link without traffic counts', () => {
    const bus = virtualBus({
      link: 'ethercat',
      traffic: null,
      ethercat: { wkc_errors: 4, missing_frames: 1, losses: 0 },
      cycle: { session: 'a-1', sync: 'freerun', configured_ms: 2, measured_ms: null, cycles: 0 },
    });
    expect(trafficText(bus)).toBe(`load ${NOT_REPORTED}`);
    expect(errorsText(bus)).toBe('2 of 120 requests failed, 4 WKC errors, 1 missing frames');
    expect(cycleText(bus)).toBe('cycle 2 ms set, — measured');
  });

  it("names a PROFINET IO AR's frames, those lost and the data-status errors", () => {
    const bus = virtualBus({
      link: 'profinet',
      interface: 'profinet',
      channel: '192.168.0.10',
      traffic: null,
      profinet: { output_frames: 12034, input_frames: 12001, lost: 3, data_status_errors: 1, losses: 1, cycle_ms: 1 },
      cycle: { session: 'a-1', sync: 'freerun', configured_ms: 1, measured_ms: 1.0012, cycles: 12030 },
    });
    expect(trafficText(bus)).toBe('12,034 frames sent, 12,001 received');
    expect(errorsText(bus)).toBe('2 of 120 requests failed, 3 frames lost, 1 data-status errors, link lost 1×');
    expect(cycleText(bus)).toBe('cycle 1 ms set, 1.001 ms measured');
  });
});

describe('live link state', () => {
  it('takes a session lost from the WebSocket at once and names the node', () => {
    const bus = withLiveSessions(virtualBus(), live({ 'a-1': true, 'b-2': false }));
    expect(bus.state).toBe('degraded');
    expect(stateText(bus)).toBe('link degraded (node 2 not answering)');
    expect(withLiveSessions(virtualBus(), live({ 'a-1': false, 'b-2': false })).state).toBe('down');
  });

  it("keeps an EtherCAT line's own state over the sessions' polls", () => {
    const line = virtualBus({ state: 'reconnecting', ethercat: { wkc_errors: 0, missing_frames: 9, losses: 1 } });
    expect(withLiveSessions(line, live({ 'a-1': true, 'b-2': true })).state).toBe('reconnecting');
  });

  it("keeps a PROFINET IO AR's lost link while its supervisor AR still answers", () => {
    const io = { output_frames: 900, input_frames: 700, lost: 0, data_status_errors: 0, losses: 1, cycle_ms: 1 };
    const bus = virtualBus({ link: 'profinet', state: 'down', profinet: io });
    expect(withLiveSessions(bus, live({ 'a-1': true, 'b-2': true })).state).toBe('down');
  });

  it('announces a change of state only', () => {
    const up = [virtualBus()];
    expect(stateChanges(up, [virtualBus({ requests: 999 })])).toBe('');
    expect(stateChanges(up, [virtualBus({ state: 'down' })])).toBe('CANopen virtual servodesk-sim: link down');
  });
});

describe('the store in the status bar (issue 49)', () => {
  function store(over: Partial<StoreStatus> = {}): StoreStatus {
    return {
      engine: 'postgresql',
      url: 'postgresql+psycopg://servodesk:***@db.plant:5432/servodesk',
      reachable: true,
      since: null,
      queued: { backups: 0, tuning_results: 0, audit_log: 0 },
      last_sync: null,
      last_error: null,
      synced: 0,
      ...over,
    };
  }

  it('says a central store is ok, and a SQLite store is the local file', () => {
    expect(storeText(store())).toBe('store: PostgreSQL ok');
    expect(storeState(store())).toBe('up');
    expect(storeText(store({ engine: 'sqlite', url: 'sqlite:////data/servodesk.db', queued: {} }))).toBe(
      'store: SQLite (local file)',
    );
  });

  it('says since when the store is unreachable and how much the gateway keeps meanwhile', () => {
    const since = new Date(2026, 11, 7, 12, 3, 40).getTime() / 1000;
    const lost = store({
      reachable: false,
      since,
      queued: { backups: 2, tuning_results: 1, audit_log: 11 },
      last_error: 'connection refused',
    });
    expect(storeText(lost)).toBe('store: unreachable since 12:03, 14 records queued locally');
    expect(storeState(lost)).toBe('down');
    expect(queuedCount(lost)).toBe(14);
    expect(storeTitle(lost)).toContain('last error: connection refused');
    expect(storeTitle(lost)).toContain('2 backups, 1 tuning results, 11 audit log');
  });

  it('shows the queue draining once the store answers again', () => {
    const draining = store({ queued: { backups: 1, tuning_results: 0, audit_log: 0 }, last_sync: 1, synced: 3 });
    expect(storeText(draining)).toBe('store: PostgreSQL ok, syncing 1 record');
    expect(storeState(draining)).toBe('degraded');
    expect(storeTitle(draining)).toContain('3 records since start');
  });
});
