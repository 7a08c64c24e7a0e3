/**
 * Pure helpers of the Tuning page: the safety inputs and the window in position units, the
 * gain table (old -> new, with units and raw values), and the series of the step-response and
 * Bode plots. No React, no DOM: unit-tested in tuningModel.test.ts.
 */
import type { Bode, GainRow, JobState, Refit, ResultGain, StepResponse, TuningInfo, TuningJob, TuningKind, TuningMode } from '../../api/tuning';

export interface Inputs {
  mode: TuningMode;
  /** As typed: text, so a half-typed number is not lost. */
  travel: string;
  torque: string;
  /** The peak torque of the machine's moves [% of rated]; empty: the torque limit. */
  moveTorque?: string;
}

export interface InputCheck {
  travel: string | null;
  torque: string | null;
  /** The window beyond the software limits (the server refuses it too). */
  window: string | null;
  ok: boolean;
  travelRev: number | null;
  torquePct: number | null;
  moveTorque: string | null;
  /** null: not given (the server takes the torque limit). */
  moveTorquePct: number | null;
}

/** A decimal number from the user's text ("0,5" too); null when it is not one. */
export function parseDecimal(text: string): number | null {
  const t = text.trim().replace(',', '.');
  if (!/^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$/.test(t)) return null;
  const v = Number(t);
  return Number.isFinite(v) ? v : null;
}

export interface Window {
  /** Half the window in position units (the axis stays within start ± half). */
  half: number;
  lo: number;
  hi: number;
}

/** The travel window in position units, centred on ``actual``: the window is its total width,
 * and half of it is rounded down so that the bound is never wider than confirmed. The server's
 * rule to the count, with the same floating-point operations (domain/tuning/travel.py
 * ``half_window``): the counts shown are those the drive's software limits get. */
export function windowInUnits(travelRev: number, unitsPerRev: number, actual: number): Window {
  const half = Math.max(1, Math.floor((travelRev * unitsPerRev) / 2));
  return { half, lo: actual - half, hi: actual + half };
}

/** Up to 6 significant digits, as the server writes its figures (Python's ``:.6g``). */
function g6(v: number): string {
  return String(Number(v.toPrecision(6)));
}

/** The bound in revolutions, in the position's own unit where that is not revolutions, and in
 * raw units side by side: "±0.25 rev (±90 deg) = ±32768 inc around 1000: -31768 … 33768 inc". The
 * server says it in the same words (domain/tuning/travel.py ``bound_text``, the job's
 * ``bound.text``). */
export function boundText(win: Window, pos: Pick<TuningInfo['position'], 'actual' | 'raw_unit' | 'unit' | 'scale' | 'units_per_rev'>): string {
  const raw = pos.raw_unit ? ` ${pos.raw_unit}` : '';
  const own = pos.unit && pos.scale && pos.unit !== 'rev' && pos.unit !== 'r' ? ` (±${g6(win.half * pos.scale)} ${pos.unit})` : '';
  return `±${g6(win.half / pos.units_per_rev)} rev${own} = ±${win.half}${raw} around ${pos.actual ?? '?'}: ${win.lo} … ${win.hi}${raw}`;
}

/** The confirmation the user ticks before a tuning: exactly the bound that is enforced, and by
 * what (docs/tuning.md, "Travel window"). */
export function confirmationText(kind: TuningKind, win: Window, pos: Parameters<typeof boundText>[1], torquePct: number | null): string {
  const torque = `with up to ${torquePct ?? '—'} % torque; the area is clear.`;
  if (kind === 'builtin') {
    return (
      `servodesk moves the axis between the ends of ${boundText(win, pos)} while the drive tunes itself; ` +
      `the drive's own tuning may overshoot those ends: leave room beyond them. ${torque}`
    );
  }
  return (
    `The axis stays within ${boundText(win, pos)} (where it stands now): servodesk keeps every move, its overshoot ` +
    `and a stop inside, and sets the drive's software position limits (607Dh) there while it tunes. ${torque}`
  );
}

/** The largest window [rev] that fits the software limits around ``actual``; null: no limit. */
export function largestWindow(actual: number, unitsPerRev: number, min: number | null, max: number | null): number | null {
  if (min === null && max === null) return null;
  const room = Math.min(min === null ? Infinity : actual - min, max === null ? Infinity : max - actual);
  return Math.max(0, (2 * room) / unitsPerRev);
}

export function checkInputs(inputs: Inputs, info: Pick<TuningInfo, 'limits' | 'position'>): InputCheck {
  const out: InputCheck = { travel: null, torque: null, window: null, ok: false, travelRev: null, torquePct: null, moveTorque: null, moveTorquePct: null };
  const travel = parseDecimal(inputs.travel);
  const tl = info.limits.travel_window_rev;
  if (travel === null) out.travel = 'enter the travel window in revolutions, e.g. 0.5';
  else if (travel <= tl.min || travel > tl.max) out.travel = `the window must be more than ${tl.min} and at most ${tl.max} rev`;
  else out.travelRev = travel;
  const torque = parseDecimal(inputs.torque);
  const ql = info.limits.torque_limit_pct;
  if (torque === null) out.torque = 'enter the torque limit in % of the rated torque, e.g. 100';
  else if (torque <= ql.min || torque > ql.max) out.torque = `the torque limit must be more than ${ql.min} and at most ${ql.max} %`;
  else out.torquePct = torque;
  const mtText = (inputs.moveTorque ?? '').trim();
  if (mtText) {
    const mt = parseDecimal(mtText);
    const ml = info.limits.move_torque_pct;
    if (mt === null) out.moveTorque = "enter the peak torque of the machine's moves in % of rated, e.g. 300, or leave it empty";
    else if (mt <= ml.min || mt > ml.max) out.moveTorque = `the move torque must be more than ${ml.min} and at most ${ml.max} %`;
    else out.moveTorquePct = mt;
  }
  const pos = info.position;
  if (out.travelRev !== null && pos.actual !== null) {
    const w = windowInUnits(out.travelRev, pos.units_per_rev, pos.actual);
    const lo = pos.min;
    const hi = pos.max;
    if ((lo !== null && w.lo < lo) || (hi !== null && w.hi > hi)) {
      const fits = largestWindow(pos.actual, pos.units_per_rev, lo, hi) ?? 0;
      out.window = `the window ${w.lo} .. ${w.hi} does not fit the software position limits ${lo ?? '−∞'} .. ${hi ?? '+∞'}; at most ${Math.floor(fits * 1000) / 1000} rev fits here`;
    }
  }
  out.ok = out.travel === null && out.torque === null && out.moveTorque === null && out.window === null;
  return out;
}

export const MODE_TEXT: Record<TuningMode, string> = {
  low: 'Low response: the softest gains, for machines that must not ring (low mode)',
  basic: 'Basic: the usual choice (basic mode)',
  high: 'High response: the stiffest gains the drive accepts (high mode)',
};

/** The radio label of a response level, with what the tuning promises at that level where the
 * server says (GET .../tuning `mode_notes`: servodesk's own tuning; the drive's own says nothing). */
export function modeText(mode: TuningMode, notes?: Partial<Record<TuningMode, string>>): string {
  const note = notes?.[mode];
  return MODE_TEXT[mode] + (note ? `; ${note}` : '');
}

export function kindTitle(kind: TuningKind): string {
  if (kind === 'builtin') return "The drive's own one-touch tuning";
  if (kind === 'gains') return "servodesk's own one-touch tuning";
  return 'Nothing to tune';
}

export function jobLabel(job: Pick<TuningJob, 'state' | 'progress' | 'step'>): string {
  const pct = Math.round(Math.max(0, Math.min(1, job.progress)) * 100);
  const what: Record<JobState, string> = { running: 'running', done: 'done', failed: 'failed', stopped: 'stopped' };
  return job.state === 'running' ? `${pct} % · ${job.step}` : `${what[job.state]} · ${job.step}`;
}

/** A number for a table cell: up to 4 significant digits, no exponent for everyday sizes. */
export function fmtNumber(v: number | null | undefined, digits = 4): string {
  if (v === null || v === undefined || !Number.isFinite(v)) return '—';
  const a = Math.abs(v);
  if (a !== 0 && (a >= 1e6 || a < 1e-3)) return v.toExponential(digits - 1);
  return String(Number(v.toPrecision(digits)));
}

/** A raw value as the drive holds it: integers as they are, REAL32 to 7 significant digits. */
export function fmtRaw(v: number | string | null | undefined): string {
  if (v === null || v === undefined) return '—';
  if (typeof v === 'string') return v;
  if (!Number.isFinite(v)) return String(v);
  return Number.isInteger(v) ? String(v) : String(Number(v.toPrecision(7)));
}

/** A unit for a table cell: dimensionless ("1") shows nothing. */
function cellUnit(unit: string | null | undefined): string {
  return !unit || unit === '1' ? '' : unit;
}

export function withUnit(v: number | null | undefined, unit: string | null | undefined, digits = 4): string {
  const n = fmtNumber(v, digits);
  return n === '—' || !unit || unit === '1' ? n : `${n} ${unit}`;
}

export interface GainLine {
  name: string;
  label: string;
  object: string;
  unit: string;
  before: string;
  after: string;
  rawBefore: string;
  rawAfter: string;
  rawUnit: string;
  /** Relative change after/before - 1 (null: not comparable). */
  change: number | null;
  changed: boolean;
}

/** The gain table of a result: old -> new with units, raw values beside them. */
export function gainLines(gains: readonly ResultGain[]): GainLine[] {
  return gains.map((g) => {
    const b = g.before;
    const a = g.after;
    const change = b !== null && a !== null && b !== 0 ? a / b - 1 : null;
    return {
      name: g.name,
      label: g.label ?? g.name,
      object: g.object,
      unit: cellUnit(g.unit),
      before: fmtNumber(b),
      after: fmtNumber(a),
      rawBefore: fmtRaw(g.raw_before),
      rawAfter: fmtRaw(g.raw_after),
      rawUnit: g.raw_unit ?? '',
      change,
      changed: g.raw_before !== g.raw_after,
    };
  });
}

/** Present gains (GET /tuning) as lines with no "after". */
export function presentLines(gains: readonly GainRow[]): GainLine[] {
  return gains.map((g) => ({
    name: g.name,
    label: g.label,
    object: g.object,
    unit: cellUnit(g.unit),
    before: fmtNumber(g.value),
    after: '',
    rawBefore: g.raw === null ? (g.error ? 'unreadable' : '—') : fmtRaw(g.raw),
    rawAfter: '',
    rawUnit: g.raw_unit ?? '',
    change: null,
    changed: false,
  }));
}

export function changeText(change: number | null): string {
  if (change === null || !Number.isFinite(change)) return '';
  const pct = Math.round(change * 100);
  return pct === 0 ? '±0 %' : `${pct > 0 ? '+' : ''}${pct} %`;
}

/** uPlot data of the step responses overlaid: a shared time axis (ms), null where one of
 * them has no sample, and the target as a third series. Positions stay in the drive's units. */
export function stepSeries(before: StepResponse | null, after: StepResponse | null): (number | null)[][] {
  const sets = [before, after];
  const times = new Set<number>();
  for (const s of sets) if (s) for (const t of s.t_s) times.add(Math.round(t * 1e6) / 1e3);
  const t = [...times].sort((x, y) => x - y);
  const index = new Map(t.map((x, i) => [x, i]));
  const cols = sets.map((s) => {
    const col: (number | null)[] = new Array<number | null>(t.length).fill(null);
    if (s) s.t_s.forEach((tt, i) => {
      const k = index.get(Math.round(tt * 1e6) / 1e3);
      if (k !== undefined) col[k] = s.position[i] ?? null;
    });
    return col;
  });
  const target = (before ?? after)?.target ?? null;
  return [t, cols[0] ?? [], cols[1] ?? [], t.map(() => target)];
}

/** uPlot data of a Bode plot: frequency (> 0 only, log axis) with magnitude and phase of the
 * measurement and the model (null where the model has none). */
export function bodeSeries(b: Bode): { freq: number[]; mag: (number | null)[][]; phase: (number | null)[][] } {
  const freq: number[] = [];
  const mm: (number | null)[] = [];
  const pm: (number | null)[] = [];
  const mmod: (number | null)[] = [];
  const pmod: (number | null)[] = [];
  b.freq_hz.forEach((f, i) => {
    if (!(f > 0) || !Number.isFinite(f)) return;
    freq.push(f);
    mm.push(num(b.measured_mag_db[i]));
    pm.push(num(b.measured_phase_deg[i]));
    mmod.push(num(b.model_mag_db?.[i]));
    pmod.push(num(b.model_phase_deg?.[i]));
  });
  return { freq, mag: [mm, mmod], phase: [pm, pmod] };
}

function num(v: number | null | undefined): number | null {
  return v === null || v === undefined || !Number.isFinite(v) ? null : v;
}

/** The Stop button shows while a job runs; the inputs are locked then. */
export function isRunning(job: Pick<TuningJob, 'state'> | null | undefined): boolean {
  return job?.state === 'running';
}

/** A log-frequency tick's label: decades only (1, 10, 100, 1k, 10k), the rest unlabelled. */
export function decadeLabel(v: number | null): string {
  if (v === null || !(v > 0)) return '';
  const e = Math.log10(v);
  if (Math.abs(e - Math.round(e)) > 1e-9) return '';
  return v >= 1000 ? `${v / 1000}k` : `${v}`;
}

/** A factor on an identified value as a signed percentage ("+2.2 %", "-0.35 %"). */
function offPct(factor: number): string {
  const p = 100 * (factor - 1);
  return `${p >= 0 ? '+' : '−'}${fmtNumber(Math.abs(p), 2)} %`;
}

/** What the winner's try on the axis told about the inertias, in the Tuning page's words:
 * the fit (motor and load against the identification, the replay's position error RMS before
 * and after, in counts) and what servodesk did with it. */
export function refitLines(r: Refit): { fit: string; outcome: string } {
  const fit =
    `motor ${offPct(r.motor_inertia_factor)}, load ${offPct(r.load_inertia_factor)} off the identification` +
    (r.total_held ? ', the total held (the test moves measured it) ' : ' ') +
    `(replay's position error RMS ${fmtNumber(r.error_rms_counts_before, 3)} → ${fmtNumber(r.error_rms_counts_after, 3)} counts)`;
  const ms = (s: number | null) => (s === null ? '—' : `${fmtNumber(1e3 * s, 3)} ms`);
  let outcome: string;
  if (r.outcome === 'searched_again') {
    outcome =
      r.first_settling_s === null
        ? `gains searched again on the fitted model: its pick settles in ${ms(r.searched_settling_s)} there, taken`
        : `gains searched again on the fitted model: its pick settles in ${ms(r.searched_settling_s)} there, the first pick in ${ms(r.first_settling_s)}; taken`;
  } else if (r.outcome === 'first_kept') {
    outcome = `gains searched again on the fitted model: its pick settles in ${ms(r.searched_settling_s)} there, the first pick in ${ms(r.first_settling_s)}; not clearly ahead (under 0.7 ×), the first kept`;
  } else {
    outcome = 'the fit was not clearly closer to the axis (error not halved, or no inertia moved by 0.5 %): the identified model kept';
  }
  return { fit, outcome };
}
