/**
 * Homing facts the Operation page shows (CiA 402-2 §6.8): the run's state decoded from
 * statusword bits 13 (homing error), 12 (homing attained) and 10 (target reached) in homing
 * mode (6061h = 6), the same table as backend/servodesk/services/homing.py, and the names of
 * the signals a method uses.
 */
import type { HomingOutcome, HomingRun, HomingSignal, HomingState, HomingStatus, MotionStatus } from '../api/types';

export const HOMING_MODE = 6;
export const SW_TARGET_REACHED = 1 << 10;
export const SW_HOMING_ATTAINED = 1 << 12;
export const SW_HOMING_ERROR = 1 << 13;

/** CiA 402-2 §6.8.1 table: bits 13/12/10 -> the state of the homing run. */
export function decodeHoming(statusword: number, mode: number | null | undefined): HomingState {
  if (mode !== HOMING_MODE) return 'idle';
  if (statusword & SW_HOMING_ERROR) return 'error';
  const attained = (statusword & SW_HOMING_ATTAINED) !== 0;
  const reached = (statusword & SW_TARGET_REACHED) !== 0;
  if (attained && reached) return 'attained';
  if (reached) return 'idle'; // Interrupted or not started.
  return 'running';
}

export const HOMING_STATE_TEXT: Record<HomingState, string> = {
  idle: 'not started or interrupted',
  running: 'in progress',
  attained: 'attained: the position is the home offset (607Ch)',
  error: 'error: a required switch was not found or a limit was reached',
};

export const SIGNAL_LABELS: Record<HomingSignal, string> = {
  home_switch: 'Home switch',
  limit_negative: 'Negative limit switch',
  limit_positive: 'Positive limit switch',
  index: 'Index pulse',
};

export function signalLabel(s: string): string {
  return (SIGNAL_LABELS as Record<string, string>)[s] ?? s.replace(/_/g, ' ');
}

// The run: its end state, progress and time-out (backend services/homing.py) --------------

/** What the panel says for each way a run ends (and while it runs). */
export const HOMING_OUTCOME_LABEL: Record<HomingOutcome, string> = {
  running: 'running',
  attained: 'attained',
  error: 'error',
  halted: 'halted',
  stopped: 'quick-stopped',
  deadman: 'stopped by the dead-man',
  control_lost: 'stopped: control lost',
  timeout: 'timed out',
  interrupted: 'interrupted',
};

/** The motion's end state (GET /motion, WebSocket `motion`) as the run's outcome. */
const OUTCOME_OF_MOTION: Record<string, HomingOutcome> = {
  done: 'attained',
  reached: 'attained',
  error: 'error',
  halted: 'halted',
  stopped: 'stopped',
  deadman: 'deadman',
  timeout: 'timeout',
  replaced: 'interrupted',
};

export function outcomeOfMotion(state: string): HomingOutcome {
  return OUTCOME_OF_MOTION[state] ?? 'interrupted';
}

/**
 * The run as the motion that carried it says it ended, or null when the motion says nothing
 * about it: the backend ends a watched run with its motion and publishes that end as the last
 * `homing` message; this is the same end taken from the `motion` message, for a tab that
 * missed the `homing` one. Only a homing motion that has ended ends a watched run still shown
 * as running.
 */
export function endFromMotion(run: HomingRun, motion: Pick<MotionStatus, 'kind' | 'active' | 'state' | 'message'>): HomingRun | null {
  if (!run.active || !run.watched || motion.kind !== 'homing' || motion.active) return null;
  return { ...run, active: false, outcome: outcomeOfMotion(motion.state), message: motion.message };
}

/**
 * Which of two homing statuses of the same session the panel keeps: a run never starts again,
 * so an answer that shows a run running after that same run was seen ended is stale (a start
 * request answered after the run's end arrived over the WebSocket).
 */
export function newerHoming(current: HomingStatus | null, next: HomingStatus): HomingStatus {
  const a = current?.run;
  const b = next.run;
  if (current && a && b && a.id === b.id && !a.active && b.active) return current;
  if (current && a && b && b.started_at < a.started_at) return current; // An older run's.
  return next;
}

/** The panel's state chip: the run's outcome when servodesk started a run, else the live
 * statusword's bits (polled at 20 Hz), else the last status read. */
export function homingShown(homing: HomingStatus | null, decoded: HomingState | null): { key: string; label: string } {
  const run = homing?.run;
  if (run) return { key: run.outcome, label: HOMING_OUTCOME_LABEL[run.outcome] };
  const state = decoded ?? homing?.state ?? 'idle';
  return { key: state, label: state };
}

/** "2.5 s", "42 s", "3 min 20 s", "3 h 43 min" (the backend's format_seconds). */
export function formatDuration(seconds: number): string {
  const s = Math.max(0, seconds);
  if (s < 10) return `${Number(s.toPrecision(2))} s`;
  if (s < 100) return `${Math.round(s)} s`;
  const r = Math.round(s);
  const m = Math.floor(r / 60);
  if (m < 60) return `${m} min ${r % 60} s`;
  return `${Math.floor(m / 60)} h ${m % 60} min`;
}

/** The time-out field: empty = the default from the estimate; else 0 < s <= 86400. */
export function parseTimeout(text: string): { value: number | null; error: string | null } {
  const t = text.trim();
  if (t === '') return { value: null, error: null };
  const v = Number(t);
  if (!Number.isFinite(v)) return { value: null, error: 'not a number' };
  if (v <= 0 || v > 86400) return { value: null, error: 'between 0 and 86400 s' };
  return { value: v, error: null };
}
