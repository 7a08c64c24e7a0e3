/**
 * The status bar at the foot of every page (issue 48, "Many axes at a glance"): per bus of
 * the open sessions, its link state, traffic, error counters and cycle time.
 *
 * The numbers come from GET /status once a second (counts the links keep: asking makes no bus
 * traffic); a session's link lost or restored comes from the WebSocket's `sessions` message
 * at once. Only a change of a bus's state is announced (a polite live region of its own):
 * the counters change every second and would drown a screen reader. Last, the store: "store:
 * PostgreSQL ok", or unreachable since when with the records the gateway keeps in its local
 * queue meanwhile (issue 49, docs/deployment.md); its change of state is announced too.
 */
import { useEffect, useRef, useState } from 'react';
import { api } from '../api/client';
import type { BusStatus, StoreStatus } from '../api/types';
import {
  busTitle,
  cycleText,
  errorsText,
  stateChanges,
  stateText,
  storeState,
  storeText,
  storeTitle,
  trafficText,
  withLiveSessions,
} from '../lib/statusBar';
import { useObservable } from '../state/observable';
import { sessions } from '../state/store';
import './statusBar.css';

/** How often the numbers are asked for [ms]: at most 1 Hz (the rates are 5 s averages). */
export const STATUS_POLL_MS = 1000;

export function StatusBar() {
  const [polled, setPolled] = useState<BusStatus[] | null>(null);
  const [store, setStore] = useState<StoreStatus | null>(null);
  const [failed, setFailed] = useState<string | null>(null);
  const [announce, setAnnounce] = useState('');
  const live = useObservable(sessions);
  const shown = useRef<BusStatus[]>([]);
  const shownStore = useRef<boolean | null>(null);

  useEffect(() => {
    let stop = false;
    let timer: ReturnType<typeof setTimeout> | null = null;
    const poll = async () => {
      try {
        const answer = await api.status();
        if (stop) return;
        setPolled(answer.buses);
        setStore(answer.store);
        setFailed(null);
      } catch (e) {
        // Not a notice: the header's connection indicator already says the server is away.
        if (!stop) setFailed(e instanceof Error ? e.message : String(e));
      }
      if (!stop) timer = setTimeout(() => void poll(), STATUS_POLL_MS);
    };
    void poll();
    return () => {
      stop = true;
      if (timer !== null) clearTimeout(timer);
    };
  }, []);

  const buses = (polled ?? []).map((b) => withLiveSessions(b, live));

  useEffect(() => {
    const changes = [stateChanges(shown.current, buses)];
    shown.current = buses;
    // The store's reachability, announced when it changes (not its counts: they tick).
    if (store !== null) {
      if (shownStore.current !== null && store.reachable !== shownStore.current) changes.push(storeText(store));
      shownStore.current = store.reachable;
    }
    const change = changes.filter(Boolean).join('. ');
    if (change) setAnnounce(change);
  });

  return (
    <footer className="status-bar" data-testid="status-bar" aria-label="Bus status">
      <span className="status-bar-announce" role="status" aria-live="polite" data-testid="status-bar-announce">
        {announce}
      </span>
      {polled === null && !failed && <span className="status-bar-empty">Bus status: —</span>}
      {failed && (
        <span className="status-bar-empty" title={failed} data-testid="status-bar-failed">
          Bus status not available
        </span>
      )}
      {polled !== null && buses.length === 0 && (
        <span className="status-bar-empty">No bus open</span>
      )}
      {buses.map((b) => (
        <div
          key={`${b.interface} ${b.channel}`}
          className="status-bus"
          data-testid={`status-bus-${b.interface}`}
          data-state={b.state}
          title={[busTitle(b), b.reason, errorsText(b), b.traffic?.load_basis].filter(Boolean).join('\n')}
        >
          <span className={`status-dot status-dot-${b.state}`} aria-hidden="true" />
          <span className="status-bus-name">{busTitle(b)}</span>
          <span className="status-bus-state" data-testid="status-bus-state">
            {stateText(b)}
          </span>
          <span data-testid="status-bus-traffic">{trafficText(b)}</span>
          <span data-testid="status-bus-cycle">{cycleText(b)}</span>
          <span className="status-bus-errors" data-testid="status-bus-errors">
            {errorsText(b)}
          </span>
        </div>
      ))}
      {store && (
        <div
          className="status-bus status-store"
          data-testid="status-store"
          data-state={storeState(store)}
          title={storeTitle(store)}
        >
          <span className={`status-dot status-dot-${storeState(store)}`} aria-hidden="true" />
          <span className="status-bus-state" data-testid="status-store-text">
            {storeText(store)}
          </span>
        </div>
      )}
    </footer>
  );
}
