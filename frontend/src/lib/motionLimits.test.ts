import { describe, expect, it } from 'vitest';
import type { Limits } from '../api/types';
import {
  byField,
  checkCyclic,
  checkHoming,
  checkJog,
  checkMove,
  checkTorque,
  checkVelocity,
  cyclicUnavailable,
  defaultAcceleration,
  rampKind,
  defaultVelocity,
  entryText,
  formatQuantity,
  parseEntry,
  permissiveLimits,
} from './motionLimits';

// GET /limits of the simulated generic drive (cia402-generic), as the backend answers it.
const GENERIC: Limits = {
  position_min: -100_000,
  position_max: 100_000,
  max_velocity: 1_000_000,
  max_torque: 3000,
  max_acceleration: null,
  max_deceleration: 500_000,
  modes: [1, 3, 4, 6],
  mode_names: {},
  units: {
    position: { raw_unit: 'inc', unit: 'deg', scale: 0.00274658203125 },
    velocity: { raw_unit: 'inc/s', unit: 'rpm', scale: 0.000457763671875 },
    torque: { raw_unit: '0.1 %', unit: '%', scale: 0.1 },
    acceleration: { raw_unit: 'inc/s²', unit: 'rpm/s', scale: 0.000457763671875 },
  },
  sources: { max_velocity: '0x607F:00', max_deceleration: '0x60C6:00', position_max: '0x607D:02' },
};

describe('units', () => {
  it('parses raw input as whole increments and engineering input through the scale', () => {
    const v = GENERIC.units.velocity;
    expect(parseEntry('100000', 'raw', v)).toEqual({ ok: true, raw: 100000 });
    expect(parseEntry('12.6', 'raw', v)).toEqual({ ok: true, raw: 13 });
    // 60 rpm at 2^17 inc/rev = 131072 inc/s.
    expect(parseEntry('60', 'eng', v)).toEqual({ ok: true, raw: 131072 });
    expect(parseEntry('  ', 'eng', v)).toEqual({ ok: true, raw: null });
    expect(parseEntry('fast', 'raw', v).ok).toBe(false);
  });

  it('shows a value in the other unit system after a switch', () => {
    const p = GENERIC.units.position;
    expect(entryText(131072, 'eng', p)).toBe('360');
    expect(entryText(131072, 'raw', p)).toBe('131072');
    expect(entryText(null, 'eng', p)).toBe('');
  });

  it('formats raw with engineering beside it, and only raw when they are the same', () => {
    expect(formatQuantity(131072, GENERIC.units.velocity)).toBe('131072 inc/s (60 rpm)');
    expect(formatQuantity(5, { raw_unit: 'inc', unit: 'inc', scale: 1 })).toBe('5 inc');
    expect(formatQuantity(null, GENERIC.units.velocity)).toBe('—');
  });
});

describe('jog check', () => {
  it('accepts a jog within the limits', () => {
    expect(checkJog({ velocity: -100000, acceleration: 400000 }, GENERIC)).toEqual([]);
  });

  it('refuses a velocity above 607Fh and names the limit and its source', () => {
    const p = byField(checkJog({ velocity: 2_000_000, acceleration: 1000 }, GENERIC));
    expect(p.velocity).toContain('max velocity');
    expect(p.velocity).toContain('0x607F:00');
  });

  it('checks the jog acceleration against the deceleration limit too (it is both)', () => {
    const p = byField(checkJog({ velocity: 1000, acceleration: 600_000 }, GENERIC));
    expect(p.acceleration).toContain('max deceleration');
  });

  it('refuses zero velocity and a non-positive acceleration', () => {
    const p = byField(checkJog({ velocity: 0, acceleration: 0 }, GENERIC));
    expect(p.velocity).toBeDefined();
    expect(p.acceleration).toBeDefined();
  });

  it('refuses a jog on a family without profile velocity', () => {
    expect(byField(checkJog({ velocity: 10, acceleration: 10 }, { ...GENERIC, modes: [1] })).mode).toContain('profile velocity');
  });
});

describe('move check', () => {
  it('checks a relative move at its end position from the actual position', () => {
    const req = { mode: 'relative' as const, target: 60_000, velocity: null, acceleration: null, deceleration: null };
    expect(checkMove(req, GENERIC, 0)).toEqual([]);
    const p = byField(checkMove(req, GENERIC, 50_000));
    expect(p.target).toContain('above the software limit');
    expect(p.target).toContain('0x607D:02');
  });

  it('checks an absolute target directly', () => {
    const p = byField(checkMove({ mode: 'absolute', target: -100_001 }, GENERIC, 99_999));
    expect(p.target).toContain('below the software limit');
  });

  it('lets the optional profile values be left out, but not be zero', () => {
    expect(checkMove({ mode: 'absolute', target: 10 }, GENERIC, null)).toEqual([]);
    expect(byField(checkMove({ mode: 'absolute', target: 10, velocity: 0 }, GENERIC, null)).velocity).toBeDefined();
  });

  it('has nothing to check against without limits but the request ranges', () => {
    expect(checkMove({ mode: 'absolute', target: 2 ** 31 }, permissiveLimits([1]), null)).toHaveLength(1);
    expect(checkMove({ mode: 'absolute', target: 2 ** 31 - 1 }, permissiveLimits([1]), null)).toEqual([]);
  });
});

describe('velocity, torque, cyclic, homing checks', () => {
  it('checks |velocity| in both directions', () => {
    expect(byField(checkVelocity({ velocity: -1_000_001 }, GENERIC)).velocity).toBeDefined();
    expect(checkVelocity({ velocity: -1_000_000 }, GENERIC)).toEqual([]);
  });

  it('checks torque against 6072h', () => {
    expect(byField(checkTorque({ torque: 3001 }, GENERIC)).torque).toContain('max torque');
    expect(checkTorque({ torque: -3000, slope: 100 }, GENERIC)).toEqual([]);
  });

  it('explains why a cyclic mode is not there', () => {
    expect(cyclicUnavailable(GENERIC, 'csp')).toContain('6060h = 8');
    expect(cyclicUnavailable({ modes: [8] }, 'csp')).toBeNull();
  });

  it('checks the csp sine peak velocity (2πfA) and the swing against the position limits', () => {
    const lim = { ...GENERIC, modes: [8, 9, 10] };
    // 2π * 1 Hz * 200000 = 1.26e6 > 1e6, and ±200000 crosses ±100000.
    const p = checkCyclic({ mode: 'csp', waveform: 'sine', amplitude: 200_000, frequency: 1, duration: 1 }, lim, 0);
    expect(p.map((x) => x.message).join(' ')).toContain('max velocity');
    expect(p.map((x) => x.message).join(' ')).toContain('software limit');
    expect(checkCyclic({ mode: 'csp', waveform: 'ramp', amplitude: 50_000, frequency: 1, duration: 1 }, lim, 0)).toEqual([]);
  });

  it('refuses cyclic frequencies and durations out of range', () => {
    const lim = { ...GENERIC, modes: [10] };
    const p = byField(checkCyclic({ mode: 'cst', waveform: 'sine', amplitude: 10, frequency: 11, duration: 61 }, lim, null));
    expect(p.frequency).toBeDefined();
    expect(p.duration).toBeDefined();
  });

  it('checks the homing method against the documented list', () => {
    expect(byField(checkHoming({ method: 17 }, [35, 37])).method).toContain('not documented');
    expect(checkHoming({ method: 37, offset: -5, speed_switch: 100 }, [35, 37])).toEqual([]);
    expect(byField(checkHoming({ method: 37, speed_zero: -1 }, [37])).speed_zero).toBeDefined();
  });

  it('checks the maximum travel and the time-out of a homing run', () => {
    expect(checkHoming({ method: 1, max_travel: 707788, timeout_s: 90.5 }, [1])).toEqual([]);
    expect(byField(checkHoming({ method: 1, max_travel: 0 }, [1])).max_travel).toBeDefined();
    expect(byField(checkHoming({ method: 1, timeout_s: 0 }, [1])).timeout_s).toBeDefined();
    expect(byField(checkHoming({ method: 1, timeout_s: 90000 }, [1])).timeout_s).toBeDefined();
  });
});

describe('defaults', () => {
  it('starts from a tenth of the velocity limit, at most 100000, and reaches it in 0.1 s', () => {
    expect(defaultVelocity(GENERIC)).toBe(100_000);
    expect(defaultVelocity({ ...GENERIC, max_velocity: 8191 })).toBe(819);
    expect(defaultVelocity(null)).toBe(100_000);
    expect(defaultAcceleration(GENERIC, 100_000)).toBe(500_000); // capped by 60C6h
    expect(defaultAcceleration({ ...GENERIC, max_deceleration: null }, 819)).toBe(8190);
  });

  it('starts a ramp given as a time at 0.2 s, not at its gentlest limit', () => {
    // LECSN-T: 6083h / 6084h in ms (0 .. 50000) from 0 to the rated speed.
    const lecsn: Limits = {
      ...GENERIC,
      max_acceleration: 50_000,
      max_deceleration: 50_000,
      units: { ...GENERIC.units, acceleration: { raw_unit: 'ms', unit: 'ms', scale: 1, ramp: 'time' } },
    };
    expect(defaultAcceleration(lecsn, 100_000)).toBe(200);
    expect(defaultAcceleration({ ...lecsn, max_acceleration: 50 }, 100_000)).toBe(50);
    expect(rampKind(lecsn)).toBe('time');
    expect(rampKind(GENERIC)).toBe('rate');
    expect(rampKind(null)).toBe('rate');
  });

  it("starts a ramp given as a register at the family's default", () => {
    // CTMM04x: 6083h / 6084h are PMC842SR rate registers (1 .. 8191), default 100.
    const ctmm: Limits = {
      ...GENERIC,
      max_acceleration: 8191,
      max_deceleration: 8191,
      units: {
        ...GENERIC.units,
        acceleration: { raw_unit: 'PMC842SR RATE DATA', unit: null, scale: 1, default: 100, ramp: 'register' },
      },
    };
    expect(defaultAcceleration(ctmm, 819)).toBe(100);
    expect(rampKind(ctmm)).toBe('register');
    // Without a default, the rate rule as before.
    const bare: Limits = {
      ...ctmm,
      units: { ...ctmm.units, acceleration: { raw_unit: 'PMC842SR RATE DATA', unit: null, scale: 1, ramp: 'register' } },
    };
    expect(defaultAcceleration(bare, 819)).toBe(8190);
  });
});
