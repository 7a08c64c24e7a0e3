import { describe, expect, it } from 'vitest';
import type { Bode, ResultGain, StepResponse, TuningInfo } from '../../api/tuning';
import {
  bodeSeries,
  boundText,
  changeText,
  confirmationText,
  decadeLabel,
  checkInputs,
  fmtNumber,
  fmtRaw,
  gainLines,
  jobLabel,
  largestWindow,
  modeText,
  parseDecimal,
  refitLines,
  stepSeries,
  windowInUnits,
  withUnit,
} from './tuningModel';

const INFO: Pick<TuningInfo, 'limits' | 'position'> = {
  limits: { travel_window_rev: { min: 0, max: 100 }, torque_limit_pct: { min: 0, max: 300 }, move_torque_pct: { min: 0, max: 1000 } },
  position: {
    actual: 1000,
    raw_unit: 'pos units',
    unit: 'pos units',
    scale: 1,
    units_per_rev: 131072,
    units_per_rev_source: 'simulation',
    min: null,
    max: null,
    limits_source: null,
  },
};

describe('safety inputs', () => {
  it('parses decimals, also with a comma, and refuses the rest', () => {
    expect(parseDecimal('0.5')).toBe(0.5);
    expect(parseDecimal(' 0,25 ')).toBe(0.25);
    expect(parseDecimal('.5')).toBe(0.5);
    expect(parseDecimal('1e1')).toBe(10);
    expect(parseDecimal('')).toBeNull();
    expect(parseDecimal('abc')).toBeNull();
    expect(parseDecimal('1.2.3')).toBeNull();
  });

  it('centres the window on the position, in position units', () => {
    expect(windowInUnits(0.5, 131072, 1000)).toEqual({ half: 32768, lo: 1000 - 32768, hi: 1000 + 32768 });
    expect(windowInUnits(1e-9, 131072, 0).half).toBe(1);
  });

  it('rounds half the window down, as the server does, so the bound is never wider than confirmed', () => {
    // 0.3 rev of 100001 units: 15000.15 either side; domain/tuning/travel.py half_window gives 15000.
    expect(windowInUnits(0.3, 100001, 0).half).toBe(15000);
    expect(windowInUnits(0.1, 1 << 20, 0).half).toBe(52428); // 52428.8
  });

  it('says the bound in revolutions, the position unit and raw units side by side, as the server', () => {
    const pos = { actual: 1000, raw_unit: 'inc', unit: 'deg', scale: 360 / 131072, units_per_rev: 131072 };
    const win = windowInUnits(0.5, 131072, 1000);
    // The same text as bound_text in tests/tuning/test_tuning_travel.py.
    expect(boundText(win, pos)).toBe('±0.25 rev (±90 deg) = ±32768 inc around 1000: -31768 … 33768 inc');
    expect(boundText(win, { ...pos, unit: null, raw_unit: null })).toBe('±0.25 rev = ±32768 around 1000: -31768 … 33768');
  });

  it('confirms exactly what is enforced, per kind of tuning', () => {
    const pos = { actual: 0, raw_unit: 'inc', unit: null, scale: 1, units_per_rev: 131072 };
    const win = windowInUnits(0.5, 131072, 0);
    const own = confirmationText('gains', win, pos, 100);
    expect(own).toContain('The axis stays within ±0.25 rev = ±32768 inc around 0: -32768 … 32768 inc');
    expect(own).toContain('607Dh');
    expect(own).toContain('up to 100 % torque');
    // The drive's own tuning: servodesk commands the ends, the drive's overshoot is its own.
    const builtin = confirmationText('builtin', win, pos, 50);
    expect(builtin).toContain('between the ends of ±0.25 rev');
    expect(builtin).toContain('may overshoot');
    expect(builtin).not.toContain('stays within');
  });

  it('names the largest window the software limits allow', () => {
    expect(largestWindow(0, 131072, null, null)).toBeNull();
    expect(largestWindow(0, 131072, -13107, 13107)).toBeCloseTo(0.2, 4);
    expect(largestWindow(10000, 131072, -13107, 13107)).toBeCloseTo((2 * 3107) / 131072, 6);
    expect(largestWindow(20000, 131072, -13107, 13107)).toBe(0);
  });

  it('checks the inputs as the server does', () => {
    const ok = checkInputs({ mode: 'basic', travel: '0.5', torque: '100' }, INFO);
    expect(ok.ok).toBe(true);
    expect(ok.travelRev).toBe(0.5);
    expect(ok.torquePct).toBe(100);
    const bad = checkInputs({ mode: 'basic', travel: '0', torque: '400' }, INFO);
    expect(bad.ok).toBe(false);
    expect(bad.travel).toContain('more than 0');
    expect(bad.torque).toContain('at most 300');
    const junk = checkInputs({ mode: 'basic', travel: 'x', torque: '' }, INFO);
    expect(junk.travel).toContain('revolutions');
    expect(junk.torque).toContain('%');
  });

  it("takes the machine's move torque as optional", () => {
    const base = { mode: 'high' as const, travel: '0.5', torque: '100' };
    const none = checkInputs({ ...base, moveTorque: ' ' }, INFO);
    expect(none.ok).toBe(true);
    expect(none.moveTorquePct).toBeNull();
    const given = checkInputs({ ...base, moveTorque: '351,2' }, INFO);
    expect(given.ok).toBe(true);
    expect(given.moveTorquePct).toBeCloseTo(351.2);
    const bad = checkInputs({ ...base, moveTorque: '1200' }, INFO);
    expect(bad.ok).toBe(false);
    expect(bad.moveTorque).toContain('at most 1000');
    expect(checkInputs({ ...base, moveTorque: 'lots' }, INFO).moveTorque).toContain('leave it empty');
  });

  it('refuses a window beyond the software limits and says what fits', () => {
    const limited = { ...INFO, position: { ...INFO.position, actual: 0, min: -13107, max: 13107 } };
    const c = checkInputs({ mode: 'low', travel: '0.5', torque: '50' }, limited);
    expect(c.ok).toBe(false);
    expect(c.window).toContain('at most 0.199 rev fits');
    expect(checkInputs({ mode: 'low', travel: '0.1', torque: '50' }, limited).ok).toBe(true);
  });
});

describe('gain table', () => {
  const gains: ResultGain[] = [
    { name: 'inertia_ratio', label: 'PB06 Load to motor inertia ratio', object: '0x2086:00', unit: 'times', raw_unit: '0.01 times', before: 7, after: 2.89, raw_before: 700, raw_after: 289 },
    { name: 'speed_integral', object: '0x208A:00', unit: 'ms', before: 33.7, after: 33.7, raw_before: 337, raw_after: 337 },
    { name: 'x', object: '0x2100:00', unit: null, before: null, after: 1, raw_before: null, raw_after: 1 },
  ];

  it('shows old -> new with units and the raw values beside them', () => {
    const [a, b, c] = gainLines(gains);
    expect(a).toMatchObject({ label: 'PB06 Load to motor inertia ratio', before: '7', after: '2.89', rawBefore: '700', rawAfter: '289', unit: 'times', rawUnit: '0.01 times', changed: true });
    expect(changeText(a!.change)).toBe('-59 %');
    expect(b).toMatchObject({ label: 'speed_integral', changed: false });
    expect(changeText(b!.change)).toBe('±0 %');
    expect(c).toMatchObject({ before: '—', rawBefore: '—', change: null });
    expect(changeText(c!.change)).toBe('');
  });

  it('formats numbers for cells', () => {
    expect(fmtNumber(118.80000000000001)).toBe('118.8');
    expect(fmtNumber(1.48e-4)).toBe('1.480e-4');
    expect(fmtNumber(null)).toBe('—');
    expect(withUnit(0.0465, 'N m s/rad')).toBe('0.0465 N m s/rad');
    expect(withUnit(1, '1')).toBe('1');
    expect(fmtRaw(0.04650000110268593)).toBe('0.0465');
    expect(fmtRaw(700)).toBe('700');
    expect(fmtRaw(null)).toBe('—');
    expect(fmtRaw('0a0b')).toBe('0a0b');
  });

  it('shows REAL32 raw values to their precision and no unit for dimensionless gains', () => {
    const [line] = gainLines([{ name: 'vel_ff', object: '0x2103:00', unit: '1', before: 1, after: 0.8, raw_before: 1, raw_after: 0.800000011920929 }]);
    expect(line).toMatchObject({ unit: '', rawAfter: '0.8' });
  });

  it('labels a job', () => {
    expect(jobLabel({ state: 'running', progress: 0.424, step: 'drive tuning 40 %' })).toBe('42 % · drive tuning 40 %');
    expect(jobLabel({ state: 'failed', progress: 0.5, step: 'failed' })).toBe('failed · failed');
  });
});

describe('plots', () => {
  const step = (t: number[], p: number[]): StepResponse => ({ t_s: t, position: p, target: 10, unit: 'inc', metrics: { settling_s: null, overshoot: null, following_error_rms: null } });

  it('overlays two step responses on one time axis in ms', () => {
    const d = stepSeries(step([0, 0.001, 0.002], [0, 5, 10]), step([0, 0.002, 0.004], [0, 9, 10]));
    expect(d[0]).toEqual([0, 1, 2, 4]);
    expect(d[1]).toEqual([0, 5, 10, null]);
    expect(d[2]).toEqual([0, null, 9, 10]);
    expect(d[3]).toEqual([10, 10, 10, 10]);
  });

  it('draws a lone step response', () => {
    const d = stepSeries(step([0, 0.001], [0, 10]), null);
    expect(d[2]).toEqual([null, null]);
  });

  it('keeps positive frequencies for the log axis and the model where it exists', () => {
    const b: Bode = {
      freq_hz: [0, 10, 100],
      measured_mag_db: [1, 2, 3],
      measured_phase_deg: [-1, -2, -3],
      coherence: [1, 1, 1],
      model_mag_db: [5, 6, Number.NaN],
      model_phase_deg: [Number.NaN, Number.NaN, Number.NaN],
    };
    const s = bodeSeries(b);
    expect(s.freq).toEqual([10, 100]);
    expect(s.mag).toEqual([[2, 3], [6, null]]);
    expect(s.phase).toEqual([[-2, -3], [null, null]]);
  });
});

describe('decadeLabel', () => {
  it('labels decades only and never prints null', () => {
    expect([1, 10, 100, 1000, 10000].map(decadeLabel)).toEqual(['1', '10', '100', '1k', '10k']);
    expect([20, 300, 5000].map(decadeLabel)).toEqual(['', '', '']);
    expect(decadeLabel(null)).toBe('');
  });
});

describe('modeText', () => {
  it("adds the server's note on what a level promises, and nothing where there is none", () => {
    const notes = { high: 'margins kept within 0.75 % of a measured resonance', basic: 'up to 2 % off' };
    expect(modeText('high', notes)).toBe('High response: the stiffest gains the drive accepts (high mode); margins kept within 0.75 % of a measured resonance');
    expect(modeText('basic', notes)).toBe('Basic: the usual choice (basic mode); up to 2 % off');
    expect(modeText('low', notes)).toBe('Low response: the softest gains, for machines that must not ring (low mode)');
    expect(modeText('high', {})).toBe('High response: the stiffest gains the drive accepts (high mode)');
    expect(modeText('high')).toBe(modeText('high', {}));
  });
});

describe('refitLines', () => {
  const base = {
    motor_inertia_factor: 0.985,
    load_inertia_factor: 0.9965,
    error_rms_counts_before: 1540.2,
    error_rms_counts_after: 83.4,
    total_held: false,
    outcome: 'first_kept' as const,
    searched_settling_s: 0.378,
    first_settling_s: 0.388,
  };
  it('gives the fit as signed percentages and the replay error in counts', () => {
    expect(refitLines(base).fit).toBe('motor −1.5 %, load −0.35 % off the identification (replay\'s position error RMS 1540 → 83.4 counts)');
  });
  it('says why the first pick stayed, with both settling times on the fitted model', () => {
    expect(refitLines(base).outcome).toBe(
      'gains searched again on the fitted model: its pick settles in 378 ms there, the first pick in 388 ms; not clearly ahead (under 0.7 ×), the first kept',
    );
  });
  it('says a new pick was taken, and when the fit was not used', () => {
    expect(refitLines({ ...base, motor_inertia_factor: 1.022, outcome: 'searched_again', searched_settling_s: 0.0122, first_settling_s: 0.0269 }).outcome).toBe(
      'gains searched again on the fitted model: its pick settles in 12.2 ms there, the first pick in 26.9 ms; taken',
    );
    expect(refitLines({ ...base, motor_inertia_factor: 1.022 }).fit.startsWith('motor +2.2 %')).toBe(true);
    expect(refitLines({ ...base, outcome: 'fit_not_used', searched_settling_s: null, first_settling_s: null }).outcome).toMatch(/identified model kept/);
  });
  it('says where only the split was fitted, the total held', () => {
    expect(refitLines({ ...base, motor_inertia_factor: 0.989, load_inertia_factor: 1.0011, total_held: true }).fit).toBe(
      'motor −1.1 %, load +0.11 % off the identification, the total held (the test moves measured it) (replay\'s position error RMS 1540 → 83.4 counts)',
    );
  });
});
