/**
 * The pure part of the drive's tuning history (issue 49; docs/ui.md "Tuning"): how a stored
 * tuning's row says when it ran, how long, how it ended and the margins and bandwidth it
 * reached. The rows are GET /sessions/{sid}/tuning/results (newest first, every session and
 * gateway); the margins come with each result (GET /tuning/results/{id}).
 */
import type { TuningRecord, TuningResult } from '../../api/tuning';
import { fmtNumber, withUnit } from './tuningModel';

/** How many of the newest rows the page opens at once to show their margins. */
export const MARGINS_FOR = 20;

export type Margins = NonNullable<TuningResult['margins']>;

/** "PM 45.2°, GM 8.1 dB"; "—" when the tuning ended without margins. */
export function marginsText(m: Margins | null | undefined): string {
  if (!m || (m.phase_margin_deg === null && m.gain_margin_db === null)) return '—';
  return `PM ${withUnit(m.phase_margin_deg, '°', 3)}, GM ${withUnit(m.gain_margin_db, 'dB', 3)}`;
}

/** "120 Hz (crossover 45.3 Hz)"; "—" when unknown. */
export function bandwidthText(m: Margins | null | undefined): string {
  if (!m || m.bandwidth_hz === null) return '—';
  const cross = m.crossover_hz === null ? '' : ` (crossover ${withUnit(m.crossover_hz, 'Hz', 3)})`;
  return `${withUnit(m.bandwidth_hz, 'Hz', 3)}${cross}`;
}

/** The words of how it ended. */
export function statusText(r: Pick<TuningRecord, 'status' | 'applied'>): string {
  const ended = r.status === 'done' ? 'finished' : r.status === 'stopped' ? 'stopped' : 'failed';
  return r.applied ? `${ended}, gains applied` : `${ended}, gains not applied`;
}

/** The job's run time: "2 min 5 s", "48 s". */
export function durationText(r: Pick<TuningRecord, 'started' | 'ended'>): string {
  const s = Math.max(0, r.ended - r.started);
  if (s < 60) return `${fmtNumber(s, 3)} s`;
  const m = Math.floor(s / 60);
  return `${m} min ${Math.round(s - m * 60)} s`;
}

/** When it ended, in the browser's local time. */
export function endedText(r: Pick<TuningRecord, 'ended'>): string {
  return new Date(r.ended * 1000).toLocaleString(undefined, { hour12: false });
}
