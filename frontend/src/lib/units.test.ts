import { describe, expect, it } from 'vitest';
import {
  ENTRY_UNIT_KEY,
  type UnitSpec,
  bothRangesText,
  engineeringToRaw,
  heldValueNote,
  loadEntryUnit,
  offersEngineeringEntry,
  parseEngineering,
  rawToEngText,
  saveEntryUnit,
  toRaw,
} from './units';

/** A velocity in inc/s shown in rpm: 3000 rpm = 491520 inc/s. */
const VEL: UnitSpec = {
  index: 0x6081,
  name: 'Profile velocity',
  data_type: 'UNSIGNED32',
  access: 'rw',
  min: null,
  max: null,
  unit: 'rpm',
  scale: 0.006103515625,
  raw_unit: 'inc/s',
  values: null,
};
/** A signed torque in 0.1 % steps (scale < 1). */
const TORQUE: UnitSpec = { ...VEL, index: 0x6071, name: 'Target torque', data_type: 'INTEGER16', unit: '%', scale: 0.1, raw_unit: '0.1 %', min: -3000, max: 3000 };
/** A position in inc shown in mm at 1000 inc per mm... inverted: 1 raw = 2.5 mm (scale > 1). */
const COARSE: UnitSpec = { ...VEL, index: 0x2001, name: 'Coarse step', data_type: 'INTEGER32', unit: 'mm', scale: 2.5, raw_unit: 'step' };
const GAIN: UnitSpec = { ...VEL, index: 0x2002, name: 'Gain', data_type: 'REAL32', unit: 'Hz', scale: 0.1, raw_unit: '0.1 Hz', min: 0, max: 10000 };

describe('offersEngineeringEntry', () => {
  it('offers it for numbers whose unit differs from the raw one', () => {
    expect(offersEngineeringEntry(VEL)).toBe(true);
    expect(offersEngineeringEntry(TORQUE)).toBe(true);
    expect(offersEngineeringEntry(GAIN)).toBe(true);
    // Same unit, other scale (1 raw = 0.5 ms).
    expect(offersEngineeringEntry({ ...VEL, unit: 'ms', raw_unit: 'ms', scale: 0.5 })).toBe(true);
  });
  it('not for objects whose raw value is already the engineering one', () => {
    expect(offersEngineeringEntry({ ...VEL, unit: 'ms', raw_unit: 'ms', scale: 1 })).toBe(false);
    expect(offersEngineeringEntry({ ...VEL, unit: null, scale: 1 })).toBe(false);
  });
  it('not for BOOLEAN, enumerations, strings and bytes', () => {
    expect(offersEngineeringEntry({ ...VEL, data_type: 'BOOLEAN' })).toBe(false);
    expect(offersEngineeringEntry({ ...VEL, values: { '0': 'off', '1': 'on' } })).toBe(false);
    expect(offersEngineeringEntry({ ...VEL, data_type: 'VISIBLE_STRING' })).toBe(false);
    expect(offersEngineeringEntry({ ...VEL, data_type: 'OCTET_STRING' })).toBe(false);
  });
  it('not with a scale that cannot be divided by', () => {
    expect(offersEngineeringEntry({ ...VEL, scale: 0 })).toBe(false);
    expect(offersEngineeringEntry({ ...VEL, scale: Number.NaN })).toBe(false);
  });
});

describe('engineeringToRaw', () => {
  it('converts an exact value and says both', () => {
    expect(engineeringToRaw(VEL, '3000')).toMatchObject({
      ok: true,
      raw: 491520,
      typed: 3000,
      engineering: 3000,
      rounded: false,
      preview: '3000 rpm = 491520 raw (inc/s)',
      note: null,
    });
  });
  it('rounds an integer object to the nearest raw step and says what that means', () => {
    const r = engineeringToRaw(VEL, '3000.004');
    expect(r).toMatchObject({ ok: true, raw: 491521, rounded: true });
    if (r.ok) {
      expect(r.engineering).toBeCloseTo(3000.006103515625, 9);
      expect(r.note).toBe('rounded to 491521 raw = 3000.006104 rpm (the drive takes whole inc/s)');
    }
    // Halves round away from zero.
    expect(engineeringToRaw(TORQUE, '-0.25')).toMatchObject({ ok: true, raw: -3, rounded: true });
  });
  it('converts negative values and scales below 1 without float noise', () => {
    // -0.3 / 0.1 is -2.9999999999999996 in floats: exactly -3 raw, not "rounded".
    expect(engineeringToRaw(TORQUE, '-0.3')).toMatchObject({ ok: true, raw: -3, rounded: false, note: null });
    expect(engineeringToRaw(TORQUE, '-150')).toMatchObject({ ok: true, raw: -1500, preview: '-150 % = -1500 raw (0.1 %)' });
  });
  it('converts with a scale above 1', () => {
    expect(engineeringToRaw(COARSE, '10')).toMatchObject({ ok: true, raw: 4, rounded: false });
    expect(engineeringToRaw(COARSE, '11')).toMatchObject({ ok: true, raw: 4, rounded: true, note: 'rounded to 4 raw = 10 mm (the drive takes whole step)' });
  });
  it('refuses a value outside the profile range, naming the range in both units', () => {
    const r = engineeringToRaw(TORQUE, '300.1');
    expect(r.ok).toBe(false);
    if (!r.ok) expect(r.message).toBe('300.1 % (3001 raw (0.1 %)) is above the maximum: allowed -300 .. 300 % (-3000 .. 3000 0.1 %)');
    const low = engineeringToRaw(TORQUE, '-301');
    expect(low.ok).toBe(false);
    if (!low.ok) expect(low.message).toContain('is below the minimum: allowed -300 .. 300 %');
  });
  it('refuses a value outside the data type, in both units', () => {
    const r = engineeringToRaw(VEL, '-1');
    expect(r.ok).toBe(false);
    if (!r.ok) expect(r.message).toBe('-1 rpm (-164 raw (inc/s)) is below the minimum: allowed 0 .. 26214399.99 rpm (0 .. 4294967295 inc/s)');
    expect(engineeringToRaw(VEL, '30000000').ok).toBe(false);
  });
  it('accepts the range edge that rounds onto it', () => {
    expect(engineeringToRaw(TORQUE, '300.04')).toMatchObject({ ok: true, raw: 3000, rounded: true });
  });
  it('does not round a REAL32 object', () => {
    expect(engineeringToRaw(GAIN, '12.34')).toMatchObject({ ok: true, rounded: false, note: null });
    const r = engineeringToRaw(GAIN, '12.34');
    if (r.ok) expect(r.raw).toBeCloseTo(123.4, 9);
    expect(engineeringToRaw(GAIN, '1000.1').ok).toBe(false);
  });
  it('refuses empty, NaN and text', () => {
    for (const t of ['', '  ', 'NaN', 'abc', '1,5', '0x10', 'Infinity', '1e999']) {
      const r = engineeringToRaw(VEL, t);
      expect(r.ok, t).toBe(false);
    }
    const r = engineeringToRaw(VEL, 'abc');
    if (!r.ok) {
      expect(r.message).toBe('"abc" is not a number');
      expect(r.hint).toContain('a decimal number in rpm');
    }
  });
  it('reads the forms people type', () => {
    expect(parseEngineering(' 1 500.5 ')).toEqual({ ok: true, value: 1500.5 });
    expect(parseEngineering('.5')).toEqual({ ok: true, value: 0.5 });
    expect(parseEngineering('+2e3')).toEqual({ ok: true, value: 2000 });
  });
});

describe('shown and typed back', () => {
  it('shows a raw value in engineering units so that typing it back gives the same raw', () => {
    const generic = { ...VEL, scale: 0.000457763671875 };
    for (const raw of [1, 200000, 123457, 4294967295]) {
      const text = rawToEngText(raw, generic);
      expect(toRaw(generic, Number(text)).raw, text).toBe(raw);
    }
    expect(rawToEngText(-3, TORQUE)).toBe('-0.3');
  });
  it('names both ranges', () => {
    expect(bothRangesText(TORQUE)).toBe('-300 .. 300 % (-3000 .. 3000 0.1 %)');
    expect(bothRangesText({ ...TORQUE, scale: -0.1 })).toBe('-300 .. 300 % (-3000 .. 3000 0.1 %)');
  });
});

describe('the browser remembers the choice', () => {
  it('defaults to engineering and keeps raw once chosen', () => {
    const m = new Map<string, string>();
    const store = { getItem: (k: string) => m.get(k) ?? null, setItem: (k: string, v: string) => void m.set(k, v) };
    expect(loadEntryUnit(store)).toBe('eng');
    saveEntryUnit('raw', store);
    expect(m.get(ENTRY_UNIT_KEY)).toBe('raw');
    expect(loadEntryUnit(store)).toBe('raw');
    expect(loadEntryUnit(null)).toBe('eng');
  });
});

describe('heldValueNote', () => {
  const rpm = { unit: 'rpm', address: '0x6081:00' };
  const raw = { unit: null, address: '0x6041:00' };

  it('keeps a number in the unit the new address takes, and empty input', () => {
    expect(heldValueNote('3000', rpm, 'rpm', '0x607F:00', 'inc/s')).toBeNull();
    expect(heldValueNote('1', raw, null, '0x6040:00', null)).toBeNull();
    expect(heldValueNote('  ', rpm, 'deg', '0x607A:00', 'inc')).toBeNull();
  });

  it('holds a number typed in another unit, naming both', () => {
    expect(heldValueNote('3000', rpm, 'deg', '0x607A:00', 'inc')).toBe(
      '“3000” is in rpm (for 0x6081:00); 0x607A:00 is entered in deg: type the value in deg.',
    );
    expect(heldValueNote('3000', rpm, null, '0x6041:00', null)).toBe('“3000” is in rpm (for 0x6081:00); 0x6041:00 takes raw values: type the raw value.');
    expect(heldValueNote('1000', raw, 'rpm', '0x6081:00', 'inc/s')).toBe(
      '“1000” is a raw value (for 0x6041:00); 0x6081:00 is entered in rpm: type it in rpm, or choose raw (inc/s).',
    );
    expect(heldValueNote('3000', rpm, null, '', null)).toContain('this address takes raw values');
  });
});
