/**
 * Homing facts the Operation page shows (CiA 402-2 §6.8): the run's state decoded from
 * statusword bits 13 (homing error), 12 (homing attained) and 10 (target reached) in homing
 * mode (6061h = 6), the same table as backend/servodesk/services/homing.py, and the names of
 * the signals a method uses.
 */
import type { HomingSignal, HomingState } from '../api/types';

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
