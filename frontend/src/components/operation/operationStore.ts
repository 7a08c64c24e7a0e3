/**
 * Live operation state per session, shared by the Operation page's panels: who holds
 * control, the running motion, the last dead-man stop, the homing run, and the heartbeat
 * loop of motion this tab started.
 *
 * Fed by the WebSocket messages `control`, `motion`, `deadman`, `homing` (docs/api.md
 * issue 4) and by the REST answers. The heartbeat loop stops when the motion this tab
 * started ended (a `motion` message that is no longer active, after one that was), when the
 * dead-man fired, or when another client took control; a poll of GET /motion backs this up in
 * case a message was missed.
 */
import type { Control, HomingStatus, MotionStatus } from '../../api/types';
import { operationApi } from '../../api/client';
import { tabClientId } from '../../lib/backupClientId';
import { HeartbeatLoop, type HeartbeatInfo } from '../../lib/heartbeat';
import { Observable } from '../../state/observable';
import { socket } from '../../state/store';
import { Fresh } from '../../lib/fresh';
import { endFromMotion, newerHoming } from '../../lib/homing';
import type { DeadmanMessage } from '../../ws/messages';

export interface OperationLive {
  control: Control | null;
  motion: MotionStatus | null;
  deadman: DeadmanMessage | null;
  homing: HomingStatus | null;
  /** performance.now() when `homing` arrived: the panel counts the elapsed time on from it. */
  homingAt: number;
  heartbeat: HeartbeatInfo;
}

interface Entry {
  obs: Observable<OperationLive>;
  /** Who holds control: pushed by messages and actions, read when a page opens (lib/fresh). */
  control: Fresh<Control>;
  loop: HeartbeatLoop;
  /** The motion this tab started was seen running since the loop started. */
  seenActive: boolean;
  /** The start request answered: a poll now tells the truth about that motion. */
  startAnswered: boolean;
  poll: ReturnType<typeof setInterval> | null;
  /** The homing run shown was seen running as a motion: that motion's end ends it. */
  homingMotionSeen: boolean;
}

const entries = new Map<string, Entry>();

export function me(): string {
  return tabClientId();
}

function entry(sid: string): Entry {
  let e = entries.get(sid);
  if (!e) {
    const loop = new HeartbeatLoop(() => socket.heartbeat(sid));
    const obs = new Observable<OperationLive>({
      control: null,
      motion: null,
      deadman: null,
      homing: null,
      homingAt: 0,
      heartbeat: loop.state,
    });
    const control = new Fresh<Control>((c) => {
      obs.update((v) => ({ ...v, control: c }));
      if (c.owner !== me()) stopHeartbeat(sid);
    });
    const created: Entry = { obs, control, loop, seenActive: false, startAnswered: false, poll: null, homingMotionSeen: false };
    loop.onChange((heartbeat) => obs.update((v) => ({ ...v, heartbeat })));
    entries.set(sid, created);
    e = created;
  }
  return e;
}

export function operationLive(sid: string): Observable<OperationLive> {
  return entry(sid).obs;
}

export function setControl(sid: string, control: Control): void {
  entry(sid).control.set(control);
}

/** GET who holds control (a page opening) and show it, unless a message or the user's own
 * action set it meanwhile: that one is newer. */
export function loadControl(sid: string): void {
  entry(sid)
    .control.read(() => operationApi.control(sid))
    .catch(() => undefined);
}

export function setMotion(sid: string, motion: MotionStatus): void {
  const e = entry(sid);
  e.obs.update((v) => ({ ...v, motion }));
  followHomingMotion(e, motion);
  if (!e.loop.running) return;
  const mine = motion.owner === me();
  if (motion.active && mine) e.seenActive = true;
  // A stale "ended" of the previous motion may arrive after a new start: only an end that
  // follows this motion's own "running" stops the heartbeat.
  else if (e.seenActive || (motion.active && !mine)) stopHeartbeat(sid);
}

/**
 * The panel follows the motion that carries a homing run: when that motion ends (attained,
 * halted, quick stop, dead-man, loss of control, time-out), so does the run shown, even if
 * the run's own last `homing` message was missed. Only a homing motion seen running while
 * this run was shown ends it (a late "ended" of the previous motion does not).
 */
function followHomingMotion(e: Entry, motion: MotionStatus): void {
  // A motion replaced by a new start is the run before: the backend ends that one itself.
  if (motion.kind !== 'homing' || motion.state === 'replaced') return;
  const h = e.obs.get().homing;
  if (motion.active) {
    if (h?.run?.active) e.homingMotionSeen = true;
    return;
  }
  if (!e.homingMotionSeen || !h?.run) return;
  e.homingMotionSeen = false;
  const ended = endFromMotion(h.run, motion);
  if (ended) e.obs.update((v) => ({ ...v, homing: { ...h, run: ended, message: ended.message }, homingAt: performance.now() }));
}

export function setHoming(sid: string, homing: HomingStatus): void {
  const e = entry(sid);
  const current = e.obs.get().homing;
  const kept = newerHoming(current, homing);
  if (kept === current) return;
  if (kept.run && kept.run.id !== current?.run?.id) {
    // Another run: whether its motion was seen running starts afresh. The motion shown now
    // may still be the one before (its end can come later than this answer); the GET /motion
    // that follows the start, or a `motion` message, says so next.
    e.homingMotionSeen = false;
  }
  e.obs.update((v) => ({ ...v, homing: kept, homingAt: performance.now() }));
}

export function clearDeadman(sid: string): void {
  entry(sid).obs.update((v) => ({ ...v, deadman: null }));
}

/** Start heartbeats for a motion this tab is about to start (before the request: the
 * server's dead-man counts from the request's arrival). */
export function beginHeartbeat(sid: string): void {
  const e = entry(sid);
  e.seenActive = false;
  e.startAnswered = false;
  e.loop.start();
  if (e.poll === null) {
    e.poll = setInterval(() => {
      if (!e.loop.running) return;
      if (!e.startAnswered) return;
      operationApi.motion(sid).then(
        (m) => {
          e.obs.update((v) => ({ ...v, motion: m }));
          if (!m.active || m.owner !== me()) stopHeartbeat(sid);
        },
        () => undefined,
      );
    }, 500);
  }
}

/** The start request answered: with its status, or failed (null) which ends the heartbeat. */
export function startAnswered(sid: string, status: MotionStatus | null): void {
  const e = entry(sid);
  if (status === null) {
    stopHeartbeat(sid);
    return;
  }
  e.startAnswered = true;
  if (status.active && status.owner === me()) e.seenActive = true;
  setMotion(sid, status);
}

export function stopHeartbeat(sid: string): void {
  const e = entries.get(sid);
  if (!e) return;
  e.loop.stop();
  e.seenActive = false;
  e.startAnswered = false;
  if (e.poll !== null) clearInterval(e.poll);
  e.poll = null;
}

export function heartbeatRunning(sid: string): boolean {
  return entries.get(sid)?.loop.running ?? false;
}

let started = false;

/** Register the socket handlers once (the socket itself is started by the shared store). */
export function startOperationStore(): void {
  if (started) return;
  started = true;
  socket.on('control', (m) => {
    setControl(m.session, { session: m.session, owner: m.owner, since: m.since, you: m.owner === me() });
  });
  socket.on('motion', (m) => {
    const { type: _type, ...status } = m;
    setMotion(m.session, status);
  });
  socket.on('deadman', (m) => {
    stopHeartbeat(m.session);
    entry(m.session).obs.update((v) => ({ ...v, deadman: m }));
  });
  socket.on('homing', (m) => {
    const { type: _type, ...status } = m;
    setHoming(m.session, status);
  });
}
