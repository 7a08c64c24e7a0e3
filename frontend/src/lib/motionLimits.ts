/**
 * Units and limits of the Operation page: converting between drive (raw) units and
 * engineering units with the profile's scale, and checking a motion request against the
 * limits the backend enforces (GET /sessions/{sid}/limits) before it is sent, so a person
 * sees which input is out of range next to the input instead of after a round trip.
 *
 * The checks mirror backend/servodesk/services/motion.py (the backend checks again; these
 * only save a refused request): |velocity| <= 607Fh, acceleration <= 60C5h (and <= 60C6h for a
 * jog, whose acceleration is also its deceleration), torque <= 6072h, a target inside the
 * software position limits 607Dh (relative: from the actual position), cyclic peak
 * velocity / acceleration from the waveform, and the request ranges of api/schemas_motion.py.
 */
import type { CyclicRequest, HomingRequest, JogRequest, Limits, MoveRequest, TorqueRequest, UnitInfo, VelocityRequest } from '../api/types';

export type Quantity = 'position' | 'velocity' | 'torque' | 'acceleration';
/** How the person types values: drive units, or engineering units (raw * scale). */
export type EntryUnits = 'raw' | 'eng';

export const I32_MIN = -(2 ** 31);
export const I32_MAX = 2 ** 31 - 1;
export const U32_MAX = 2 ** 32 - 1;
/** Period of the backend's cyclic set-point generator (MotionService.cyclic_period). */
export const CYCLIC_PERIOD_S = 0.01;

export interface FieldProblem {
  field: string;
  message: string;
}

/** A unit with a usable scale (a missing or zero scale means raw = engineering). */
export function scaleOf(unit: UnitInfo | null | undefined): number {
  const s = unit?.scale;
  return typeof s === 'number' && Number.isFinite(s) && s !== 0 ? s : 1;
}

/** The unit has an engineering unit different from the raw one. */
export function hasEngineering(unit: UnitInfo | null | undefined): boolean {
  return !!unit?.unit && (unit.unit !== unit.raw_unit || scaleOf(unit) !== 1);
}

export function rawUnitName(unit: UnitInfo | null | undefined): string {
  return unit?.raw_unit ?? 'raw';
}

export function engUnitName(unit: UnitInfo | null | undefined): string {
  return unit?.unit ?? unit?.raw_unit ?? 'raw';
}

export function toEngineering(raw: number, unit: UnitInfo | null | undefined): number {
  return raw * scaleOf(unit);
}

/** Raw (integer) value of an engineering value: the drive takes whole increments. */
export function fromEngineering(eng: number, unit: UnitInfo | null | undefined): number {
  return Math.round(eng / scaleOf(unit));
}

/** A number for display: integers as they are, others with sensible decimals. */
export function formatNumber(v: number): string {
  if (Number.isInteger(v)) return v.toString();
  const abs = Math.abs(v);
  const decimals = abs >= 1000 ? 1 : abs >= 10 ? 2 : abs >= 1 ? 3 : 4;
  return Number(v.toFixed(decimals)).toString();
}

/** "100000 inc/s (45.78 rpm)": raw with its unit, and the engineering value when it differs. */
export function formatQuantity(raw: number | null | undefined, unit: UnitInfo | null | undefined): string {
  if (raw === null || raw === undefined) return '—';
  const r = `${formatNumber(raw)} ${rawUnitName(unit)}`;
  if (!hasEngineering(unit)) return r;
  return `${r} (${formatNumber(toEngineering(raw, unit))} ${engUnitName(unit)})`;
}

export type ParsedEntry = { ok: true; raw: number | null } | { ok: false; error: string };

/**
 * Parse what the person typed, in the entry units, into a raw integer. Empty is `null` (the
 * field is optional or missing); anything else that is not a finite number is an error.
 */
export function parseEntry(text: string, entry: EntryUnits, unit: UnitInfo | null | undefined): ParsedEntry {
  const t = text.trim().replace(/\s+/g, '');
  if (t === '') return { ok: true, raw: null };
  const n = Number(t);
  if (!Number.isFinite(n)) return { ok: false, error: `"${text.trim()}" is not a number` };
  return { ok: true, raw: entry === 'raw' ? Math.round(n) : fromEngineering(n, unit) };
}

/** The text of a raw value in the entry units (for re-showing a field after a unit switch). */
export function entryText(raw: number | null, entry: EntryUnits, unit: UnitInfo | null | undefined): string {
  if (raw === null) return '';
  return entry === 'raw' ? String(raw) : formatNumber(toEngineering(raw, unit));
}

function limitText(name: string, limits: Limits, fallback: string): string {
  return limits.sources[name] ?? fallback;
}

function checkAbs(
  out: FieldProblem[],
  field: string,
  value: number,
  limit: number | null,
  limitName: string,
  limits: Limits,
  unit: UnitInfo | undefined,
  fallback: string,
): void {
  if (limit !== null && Math.abs(value) > limit) {
    out.push({
      field,
      message: `${formatQuantity(Math.abs(value), unit)} exceeds the ${limitName} ${formatQuantity(limit, unit)} (${limitText(
        limitName.replace(/ /g, '_'),
        limits,
        fallback,
      )})`,
    });
  }
}

function checkRange(out: FieldProblem[], field: string, value: number, lo: number, hi: number, what: string): boolean {
  if (!Number.isInteger(value) || value < lo || value > hi) {
    out.push({ field, message: `${what} must be a whole number from ${lo} to ${hi}` });
    return false;
  }
  return true;
}

function checkPositive(out: FieldProblem[], field: string, value: number | null | undefined, what: string): value is number {
  if (value === null || value === undefined) return false;
  if (!checkRange(out, field, value, 1, U32_MAX, what)) return false;
  return true;
}

/** The position limits 607Dh, when the drive has them on. */
export function checkPosition(out: FieldProblem[], field: string, position: number, limits: Limits): void {
  const unit = limits.units.position;
  const lo = limits.position_min;
  const hi = limits.position_max;
  if (lo !== null && position < lo) {
    out.push({
      field,
      message: `the end position ${formatQuantity(position, unit)} is below the software limit ${formatQuantity(lo, unit)} (${limitText('position_min', limits, '607Dh:01')})`,
    });
  }
  if (hi !== null && position > hi) {
    out.push({
      field,
      message: `the end position ${formatQuantity(position, unit)} is above the software limit ${formatQuantity(hi, unit)} (${limitText('position_max', limits, '607Dh:02')})`,
    });
  }
}

function needMode(out: FieldProblem[], limits: Limits, mode: number, what: string): void {
  if (!limits.modes.includes(mode)) {
    out.push({ field: 'mode', message: `this drive family has no ${MODE_LABEL[mode] ?? `mode ${mode}`}, which ${what} needs` });
  }
}

const MODE_LABEL: Record<number, string> = {
  1: 'profile position (pp)',
  3: 'profile velocity (pv)',
  4: 'profile torque (tq)',
  6: 'homing (hm)',
  8: 'cyclic synchronous position (csp)',
  9: 'cyclic synchronous velocity (csv)',
  10: 'cyclic synchronous torque (cst)',
};

export function checkJog(req: JogRequest, limits: Limits): FieldProblem[] {
  const out: FieldProblem[] = [];
  needMode(out, limits, 3, 'a jog');
  const u = limits.units;
  if (checkRange(out, 'velocity', req.velocity, I32_MIN, I32_MAX, 'velocity')) {
    if (req.velocity === 0) out.push({ field: 'velocity', message: 'a jog needs a velocity other than 0' });
    checkAbs(out, 'velocity', req.velocity, limits.max_velocity, 'max velocity', limits, u.velocity, '607Fh');
  }
  if (checkPositive(out, 'acceleration', req.acceleration, 'acceleration')) {
    checkAbs(out, 'acceleration', req.acceleration, limits.max_acceleration, 'max acceleration', limits, u.acceleration, '60C5h');
    checkAbs(out, 'acceleration', req.acceleration, limits.max_deceleration, 'max deceleration', limits, u.acceleration, '60C6h');
  }
  return out;
}

/** `actual` is the actual position (6064h), needed for a relative move's end position. */
export function checkMove(req: MoveRequest, limits: Limits, actual: number | null): FieldProblem[] {
  const out: FieldProblem[] = [];
  needMode(out, limits, 1, 'a move');
  const u = limits.units;
  if (checkRange(out, 'target', req.target, I32_MIN, I32_MAX, 'target')) {
    const end = req.mode === 'relative' ? (actual === null ? null : actual + req.target) : req.target;
    if (end !== null) checkPosition(out, 'target', end, limits);
  }
  if (checkPositive(out, 'velocity', req.velocity, 'velocity')) {
    checkAbs(out, 'velocity', req.velocity, limits.max_velocity, 'max velocity', limits, u.velocity, '607Fh');
  }
  if (checkPositive(out, 'acceleration', req.acceleration, 'acceleration')) {
    checkAbs(out, 'acceleration', req.acceleration, limits.max_acceleration, 'max acceleration', limits, u.acceleration, '60C5h');
  }
  if (checkPositive(out, 'deceleration', req.deceleration, 'deceleration')) {
    checkAbs(out, 'deceleration', req.deceleration, limits.max_deceleration, 'max deceleration', limits, u.acceleration, '60C6h');
  }
  return out;
}

export function checkVelocity(req: VelocityRequest, limits: Limits): FieldProblem[] {
  const out: FieldProblem[] = [];
  needMode(out, limits, 3, 'profile velocity');
  const u = limits.units;
  if (checkRange(out, 'velocity', req.velocity, I32_MIN, I32_MAX, 'velocity')) {
    checkAbs(out, 'velocity', req.velocity, limits.max_velocity, 'max velocity', limits, u.velocity, '607Fh');
  }
  if (checkPositive(out, 'acceleration', req.acceleration, 'acceleration')) {
    checkAbs(out, 'acceleration', req.acceleration, limits.max_acceleration, 'max acceleration', limits, u.acceleration, '60C5h');
  }
  if (checkPositive(out, 'deceleration', req.deceleration, 'deceleration')) {
    checkAbs(out, 'deceleration', req.deceleration, limits.max_deceleration, 'max deceleration', limits, u.acceleration, '60C6h');
  }
  return out;
}

export function checkTorque(req: TorqueRequest, limits: Limits): FieldProblem[] {
  const out: FieldProblem[] = [];
  needMode(out, limits, 4, 'profile torque');
  if (checkRange(out, 'torque', req.torque, I32_MIN, I32_MAX, 'torque')) {
    checkAbs(out, 'torque', req.torque, limits.max_torque, 'max torque', limits, limits.units.torque, '6072h');
  }
  checkPositive(out, 'slope', req.slope, 'torque slope');
  return out;
}

export const CYCLIC_MODE_NUMBER: Record<CyclicRequest['mode'], number> = { csp: 8, csv: 9, cst: 10 };

/** Peak rate of change of the waveform per unit amplitude (sine 2πf, triangle 4f). */
export function waveformSlope(waveform: CyclicRequest['waveform'], frequency: number): number {
  return waveform === 'sine' ? 2 * Math.PI * frequency : 4 * frequency;
}

export function checkCyclic(req: CyclicRequest, limits: Limits, actual: number | null): FieldProblem[] {
  const out: FieldProblem[] = [];
  needMode(out, limits, CYCLIC_MODE_NUMBER[req.mode], `the cyclic ${req.mode} generator`);
  const u = limits.units;
  if (!(req.frequency > 0 && req.frequency <= 10)) out.push({ field: 'frequency', message: 'frequency must be above 0 and at most 10 Hz' });
  else if (req.frequency * CYCLIC_PERIOD_S > 0.1)
    out.push({ field: 'frequency', message: `at most ${formatNumber(0.1 / CYCLIC_PERIOD_S)} Hz with set-points every ${CYCLIC_PERIOD_S * 1000} ms` });
  if (!(req.duration > 0 && req.duration <= 60)) out.push({ field: 'duration', message: 'duration must be above 0 and at most 60 s' });
  if (!(req.amplitude >= 0 && req.amplitude <= I32_MAX)) {
    out.push({ field: 'amplitude', message: `amplitude must be from 0 to ${I32_MAX}` });
    return out;
  }
  const slope = req.frequency > 0 ? waveformSlope(req.waveform, req.frequency) : 0;
  if (req.mode === 'csp') {
    if (actual !== null) {
      checkPosition(out, 'amplitude', actual + req.amplitude, limits);
      checkPosition(out, 'amplitude', actual - req.amplitude, limits);
    }
    checkAbs(out, 'amplitude', req.amplitude * slope, limits.max_velocity, 'max velocity', limits, u.velocity, '607Fh');
  } else if (req.mode === 'csv') {
    checkAbs(out, 'amplitude', req.amplitude, limits.max_velocity, 'max velocity', limits, u.velocity, '607Fh');
    checkAbs(out, 'amplitude', req.amplitude * slope, limits.max_acceleration, 'max acceleration', limits, u.acceleration, '60C5h');
  } else {
    checkAbs(out, 'amplitude', req.amplitude, limits.max_torque, 'max torque', limits, u.torque, '6072h');
  }
  return out;
}

export function checkHoming(req: HomingRequest, methods: readonly number[]): FieldProblem[] {
  const out: FieldProblem[] = [];
  if (!methods.includes(req.method)) out.push({ field: 'method', message: `method ${req.method} is not documented for this family` });
  for (const [field, v] of [
    ['speed_switch', req.speed_switch],
    ['speed_zero', req.speed_zero],
    ['acceleration', req.acceleration],
  ] as const) {
    if (v !== null && v !== undefined) checkRange(out, field, v, 0, U32_MAX, field.replace('_', ' '));
  }
  if (req.offset !== null && req.offset !== undefined) checkRange(out, 'offset', req.offset, I32_MIN, I32_MAX, 'home offset');
  if (req.max_travel !== null && req.max_travel !== undefined) checkRange(out, 'max_travel', req.max_travel, 1, U32_MAX, 'maximum travel');
  if (req.timeout_s !== null && req.timeout_s !== undefined && !(req.timeout_s > 0 && req.timeout_s <= 86400)) {
    out.push({ field: 'timeout_s', message: 'the time-out is between 0 and 86400 s' });
  }
  return out;
}

/** Problems by field, first message per field (for showing next to the inputs). */
export function byField(problems: readonly FieldProblem[]): Record<string, string> {
  const out: Record<string, string> = {};
  for (const p of problems) if (!(p.field in out)) out[p.field] = p.message;
  return out;
}

/** Why a cyclic mode cannot run on this family, or null when it can. */
export function cyclicUnavailable(limits: Pick<Limits, 'modes'>, mode: CyclicRequest['mode']): string | null {
  const n = CYCLIC_MODE_NUMBER[mode];
  if (limits.modes.includes(n)) return null;
  return `${MODE_LABEL[n]} (6060h = ${n}) is not among this family's modes of operation`;
}

/** Limits to check against when GET /limits failed: only the modes are known. */
export function permissiveLimits(modes: readonly number[]): Limits {
  return {
    position_min: null,
    position_max: null,
    max_velocity: null,
    max_torque: null,
    max_acceleration: null,
    max_deceleration: null,
    modes: [...modes],
    mode_names: {},
    units: {},
    sources: {},
  };
}

/** A starting value for a jog / move velocity: a tenth of the limit, at most 100000. */
export function defaultVelocity(limits: Limits | null): number {
  const max = limits?.max_velocity ?? null;
  return Math.max(1, Math.round(Math.min(100_000, max !== null ? max / 10 : 100_000)));
}

/** The ramp time constant a panel starts from where the family gives its ramps as times
 * (LECSN-T 6083h / 6084h: ms from 0 to the rated speed, 004 §20.9.3.10(7)). */
export const DEFAULT_RAMP_S = 0.2;

/** What the ramp objects hold, as the server decided it from the profile (GET /limits
 * `units.acceleration.ramp`, backend domain/ramps.py); a rate where it does not say. */
export function rampKind(limits: Limits | null): 'rate' | 'time' | 'register' {
  return limits?.units.acceleration?.ramp ?? 'rate';
}

/** A starting acceleration: reach `velocity` in 0.1 s, within the drive's limits. Where the
 * ramp is a time (a larger value is a gentler ramp, so the limit is the gentlest), a time
 * constant of :data:`DEFAULT_RAMP_S` instead: the rate rule capped at that limit gave the
 * LECSN-T a 50 s ramp to its rated speed, a jog that hardly moved. Where it is neither (the
 * CTMM04x's rate registers, 1..8191, larger also gentler), the family's own default of
 * 6083h: the rate rule gave 8190, some 1.6 s to the jog speed. */
export function defaultAcceleration(limits: Limits | null, velocity: number): number {
  const unit = limits?.units.acceleration;
  const kind = rampKind(limits);
  const caps = [limits?.max_acceleration ?? null, limits?.max_deceleration ?? null];
  if (kind === 'time') {
    let t = DEFAULT_RAMP_S * 1000;
    for (const m of caps) if (m !== null) t = Math.min(t, m);
    return Math.max(1, Math.round(t));
  }
  if (kind === 'register' && typeof unit?.default === 'number' && unit.default > 0) {
    let r = unit.default;
    for (const m of caps) if (m !== null) r = Math.min(r, m);
    return r;
  }
  let a = Math.abs(velocity) * 10;
  for (const m of [limits?.max_acceleration ?? null, limits?.max_deceleration ?? null]) if (m !== null) a = Math.min(a, m);
  return Math.max(1, Math.round(a));
}
