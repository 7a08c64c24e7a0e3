/**
 * REST client and shapes of the tuning routes (docs/tuning.md "Service and API", docs/api.md
 * "Tuning"): `/api/v1/sessions/{sid}/tuning...`.
 *
 * Requests go through the one fetch wrapper (`./http`), and failures become `ApiError`s
 * with the server's message and hint. The routes still answer `dict[str, Any]` (issue 51 item
 * 1): the shapes below are the UI's until the backend gives them response models.
 */
import { apiRequest, untyped } from './http';
import type { StoreResult } from './types';

export type TuningKind = 'builtin' | 'gains' | 'none';
export type TuningMode = 'low' | 'basic' | 'high';
export type JobState = 'running' | 'done' | 'failed' | 'stopped';

/** A decoded result code: the drive's (builtin: P11604 with the profile's table) or servodesk's reason. */
export interface TuningError {
  code: number | null;
  code_hex: string | null;
  name: string;
  cause: string | null;
  remedy: string | null;
  section?: string | null;
}

export interface TuningJob {
  id: string;
  session: string;
  kind: TuningKind;
  mode: string;
  state: JobState;
  progress: number;
  step: string;
  owner: string;
  started: number;
  ended: number | null;
  message: string;
  error: TuningError | null;
  travel_window_rev: number;
  /** The bound the window gives around where the axis stood (optional for an older server). */
  bound?: TravelBound | null;
  torque_limit_pct: number;
  /** The peak torque of the machine's moves the gains were ranked for (null: the limit). */
  move_torque_pct?: number | null;
}

/** The travel bound: start ± half the window [position units] (docs/tuning.md "Travel window"). */
export interface TravelBound {
  start: number;
  low: number;
  high: number;
  half: number;
  half_rev: number | null;
  raw_unit: string | null;
  /** The bound in words, revolutions and units side by side. */
  text?: string;
  /** Servodesk's own tuning: how far the axis went (from the drive's recordings). */
  lowest?: number;
  highest?: number;
  max_excursion?: number;
  max_excursion_rev?: number;
  /** Whether the drive's software position limits (607Dh) held the bound too. */
  software_limits?: boolean;
}

export interface GainRow {
  name: string;
  label: string;
  object: string;
  symbol: string | null;
  unit: string | null;
  raw_unit: string | null;
  scale: number;
  value: number | null;
  raw: number | string | null;
  default: number | string | null;
  error: string | null;
}

export interface TuningInfo {
  session: string;
  profile_id: string;
  profile_name: string;
  kind: TuningKind;
  reason: string;
  applies: { page: string; group: string; label: string }[];
  modes: TuningMode[];
  /** What servodesk's own tuning promises at each level (empty for the drive's own tuning;
   * optional for an older server). */
  mode_notes?: Partial<Record<TuningMode, string>>;
  gains: GainRow[];
  loop_rate_hz: number | null;
  defaults: { mode: TuningMode; travel_window_rev: number; torque_limit_pct: number };
  /** What the travel window means for this kind of tuning (optional for an older server). */
  travel_rule?: string | null;
  limits: {
    travel_window_rev: { min: number; max: number };
    torque_limit_pct: { min: number; max: number };
    /** Optional for an older server. */
    move_torque_pct?: { min: number; max: number };
  };
  position: {
    actual: number | null;
    raw_unit: string | null;
    unit: string | null;
    scale: number;
    units_per_rev: number;
    units_per_rev_source: string;
    min: number | null;
    max: number | null;
    limits_source: string | null;
  };
  torque_limit: { object: string | null; present_pct: number | null };
  state: string;
  step_source: 'recorder' | 'sdo' | null;
  undo: { before: boolean; defaults: boolean; note: string | null };
  job: TuningJob | null;
  result_available: boolean;
}

export interface StepMetrics {
  settling_s: number | null;
  overshoot: number | null;
  following_error_rms: number | null;
}

export interface StepResponse {
  t_s: number[];
  position: number[];
  target: number;
  unit: string;
  units_per_rev?: number;
  source?: 'recorder' | 'sdo';
  rate_hz?: number;
  note?: string;
  metrics: StepMetrics;
}

export interface Bode {
  freq_hz: number[];
  measured_mag_db: number[];
  measured_phase_deg: number[];
  coherence?: number[];
  model_mag_db?: number[];
  model_phase_deg?: number[];
}

export interface ResultGain {
  name: string;
  label?: string;
  object: string;
  symbol?: string | null;
  unit: string | null;
  raw_unit?: string | null;
  before: number | null;
  after: number | null;
  raw_before: number | string | null;
  raw_after: number | string | null;
}

export interface Identified {
  inertia_kgm2: number | null;
  inertia_ratio: number | null;
  /** The test moves' least squares: Coulomb friction [N m] and viscous friction [N m s/rad].
   * The moves run at one cruise speed, where the split between the two is not determined
   * (the fit may trade them, to a negative viscous term); their sum at that speed is
   * `moves_friction_nm`. */
  coulomb_nm: number | null;
  viscous_nms: number | null;
  /** The test moves' friction at their cruise speed, c + b v [N m]; absent from older results
   * and from the drive's own tuning. */
  moves_friction_nm?: number | null;
  /** That cruise speed [rad/s]. */
  moves_speed_rad_s?: number | null;
  gravity_nm: number | null;
  /** Coulomb friction from the frequency response's slow constant-speed travel [N m]; absent
   * from older results, null where it gave none (the moves' fit is `coulomb_nm`). */
  travel_friction_nm?: number | null;
  /** The Coulomb friction servodesk's ranking model took [N m]: the slow travel's, or the test
   * moves' c + b v at their cruise speed; absent from older results, null for the drive's own
   * tuning. */
  ranking_friction_nm?: number | null;
  resonances: {
    freq_hz: number;
    anti_freq_hz: number | null;
    peak_db: number | null;
    /** The damping ratio the design used (dimensionless); absent from older results. */
    damping?: number;
  }[];
  /** servodesk's own tuning: the inertias the winner's try on the axis fitted (factors on the
   * identified motor's and load's) and what came of it; null where no try was fitted, absent
   * from older results and from the drive's own tuning. */
  refit?: Refit | null;
}

/** `identified.refit`: the model's inertias fitted to the recordings of the winner's try. */
export interface Refit {
  motor_inertia_factor: number;
  load_inertia_factor: number;
  /** Only the split between motor and load was fitted, the total held (the test moves' double
   * integral measured it); absent from older results. */
  total_held?: boolean;
  /** The replayed try's motor position error against the recording, RMS [counts], with the
   * identified inertias and with the fitted ones. */
  error_rms_counts_before: number;
  error_rms_counts_after: number;
  /** `fit_not_used`: the fit was not clearly better (error not halved) or moved no inertia by
   * 0.5 %; `searched_again`: the gains were searched again on the fitted model and its pick
   * taken; `first_kept`: searched again, but the new pick was not clearly ahead of the first
   * on that model (under 0.7 x its settling), so the first stayed. */
  outcome: 'fit_not_used' | 'searched_again' | 'first_kept';
  /** Settling to +-10 counts on the fitted model [s]: the search's new pick and the first pick
   * (null where not searched again, or where the first pick diverged there). */
  searched_settling_s: number | null;
  first_settling_s: number | null;
}

export interface TuningResult {
  kind: TuningKind;
  status: JobState;
  error: TuningError | null;
  drive_code?: TuningError | null;
  mode: string;
  identified: Identified | null;
  bode: Bode | null;
  margins: { phase_margin_deg: number | null; gain_margin_db: number | null; crossover_hz: number | null; bandwidth_hz: number | null } | null;
  gains: ResultGain[];
  step: { before: StepResponse | null; after: StepResponse | null } | null;
  axis_time_s: number | null;
  /** The span the axis moved over, highest less lowest [rev]. */
  excursion_rev: number | null;
  /** The bound and, for servodesk's own tuning, how far from the start the axis went
   * (optional for an older server). */
  travel?: TravelBound | null;
  peak_torque_pct: number | null;
  /** Set where the peak is the largest of 6077h polls this many seconds apart (a drive's own
   * tuning): shorter peaks are not seen. Null where it comes from recordings. */
  peak_torque_polled_s?: number | null;
  applied: boolean;
  stored: boolean;
  notes?: string[];
  undone?: 'before' | 'defaults';
}

export interface StartRequest {
  mode: TuningMode;
  travel_window_rev: number;
  torque_limit_pct: number;
  /** servodesk's own tuning: the peak torque of the machine's own moves [% of rated]. */
  move_torque_pct?: number | null;
}

export interface UndoResult {
  session: string;
  to: 'before' | 'defaults';
  gains: GainRow[];
  stored: boolean;
  note: string;
}

export const tuningApi = {
  info: (sid: string) =>
    untyped(apiRequest('Read the tuning', 'GET', '/sessions/{sid}/tuning', { params: { sid } })) as Promise<TuningInfo>,
  start: (sid: string, body: StartRequest) =>
    untyped(apiRequest('Start the tuning', 'POST', '/sessions/{sid}/tuning/start', { params: { sid }, body })) as Promise<TuningJob>,
  stop: (sid: string) =>
    untyped(apiRequest('Stop the tuning', 'POST', '/sessions/{sid}/tuning/stop', { params: { sid }, body: {} })) as Promise<TuningJob>,
  result: (sid: string) =>
    untyped(apiRequest('Read the tuning result', 'GET', '/sessions/{sid}/tuning/result', { params: { sid } })) as Promise<TuningResult>,
  undo: (sid: string, to: 'before' | 'defaults') =>
    untyped(
      apiRequest(to === 'before' ? 'Undo to the gains before tuning' : 'Undo to the default gains', 'POST', '/sessions/{sid}/tuning/undo', {
        params: { sid },
        body: { to },
      }),
    ) as Promise<UndoResult>,
  store: (sid: string) =>
    untyped(apiRequest('Store to EEPROM', 'POST', '/sessions/{sid}/tuning/store', { params: { sid }, body: {} })) as Promise<
      StoreResult & { session: string }
    >,
};
