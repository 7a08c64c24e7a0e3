/**
 * Shared UI state: the one WebSocket, the list of open sessions, and each subscribed
 * session's live drive state with the last seconds of position and velocity for the plot.
 *
 * Sessions come from the socket's `sessions` message; while the socket is down the list is
 * refreshed over REST (GET /sessions) so the Connect page still works.
 */
import type { DriveState, SessionInfo } from '../api';
import { api } from '../api/client';
import { ServodeskSocket, type SocketStatusInfo } from '../ws/socket';
import type { LinkMessage } from '../ws/messages';
import { notify, notifyError } from './notify';
import { Observable } from './observable';

/** Seconds of history the Overview plot shows. */
export const HISTORY_SECONDS = 10;

export interface LiveHistory {
  t: number[];
  position: Array<number | null>;
  velocity: Array<number | null>;
}

export interface LiveSession {
  state: DriveState | null;
  history: LiveHistory;
  /** Time (ms since epoch) of the last state received. */
  received: number | null;
}

const EMPTY_LIVE: LiveSession = { state: null, history: { t: [], position: [], velocity: [] }, received: null };

export const socket = new ServodeskSocket();
export const socketStatus = new Observable<SocketStatusInfo>(socket.status);
export const sessions = new Observable<SessionInfo[] | null>(null);
const live = new Map<string, Observable<LiveSession>>();

export function liveSession(sid: string): Observable<LiveSession> {
  let obs = live.get(sid);
  if (!obs) {
    obs = new Observable<LiveSession>(EMPTY_LIVE);
    live.set(sid, obs);
  }
  return obs;
}

/** Put a drive state (from the socket or a REST answer) into the live store. */
export function applyState(sid: string, state: DriveState): void {
  const obs = liveSession(sid);
  const now = Date.now();
  const prev = obs.get();
  const t = now / 1000;
  const cut = t - HISTORY_SECONDS;
  const h = prev.history;
  let start = 0;
  while (start < h.t.length && (h.t[start] ?? 0) < cut) start++;
  const history: LiveHistory = {
    t: [...h.t.slice(start), t],
    position: [...h.position.slice(start), state.position_eng ?? state.position],
    velocity: [...h.velocity.slice(start), state.velocity_eng ?? state.velocity],
  };
  obs.set({ state, history, received: now });
  // Keep the session list's state column in step without waiting for a `sessions` message.
  const list = sessions.get();
  if (list) {
    const i = list.findIndex((s) => s.id === sid);
    const cur = i >= 0 ? list[i] : undefined;
    if (cur && cur.state !== state.state) {
      const next = list.slice();
      next[i] = { ...cur, state: state.state };
      sessions.set(next);
    }
  }
}

export async function refreshSessions(): Promise<void> {
  try {
    sessions.set(await api.sessions());
  } catch (e) {
    notifyError(e);
  }
}

let started = false;

export function startStore(): void {
  if (started) return;
  started = true;
  socket.onStatus((s) => socketStatus.set(s));
  socket.on('sessions', (m) => sessions.set(m.sessions));
  socket.on('state', (m) => {
    const { type: _type, session, ...state } = m;
    applyState(session, state);
  });
  socket.on('emcy', (m) => {
    notify({
      kind: 'warning',
      title: `EMCY ${m.code_hex} from ${m.session}: ${m.name}`,
      message: m.cause ?? 'the drive reported an emergency',
      detail: `error register 0x${m.register.toString(16).toUpperCase().padStart(2, '0')}`,
      hint: m.remedy,
    });
  });
  const LINK_EVENTS: Record<LinkMessage['event'], string> = {
    lost: 'lost the link',
    restored: 'link restored',
    closed: 'closed',
    heartbeat_lost: 'heartbeat lost',
    heartbeat_restored: 'heartbeat back',
  };
  socket.on('link', (m) => {
    const what = LINK_EVENTS[m.event];
    const good = m.event === 'restored' || m.event === 'heartbeat_restored';
    notify({
      kind: good ? 'info' : 'warning',
      title: `${m.session}: ${what}`,
      message: m.message ?? '',
      detail: null,
      hint:
        m.event === 'lost' || m.event === 'heartbeat_lost'
          ? 'check the cable, the interface and the drive power; servodesk reconnects on its own'
          : null,
    });
    if (m.event === 'closed') void refreshSessions();
  });
  socket.start();
  // The socket sends `sessions` on connect; REST fills the list now in case it cannot connect.
  void refreshSessions();
}
