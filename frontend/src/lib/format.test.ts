import { describe, expect, it } from 'vitest';
import { formatEngineering, formatRawBytes, parseNumberInput, toHex, valueToInput } from './format';

describe('toHex', () => {
  it('pads to the type width', () => {
    expect(toHex(0x27, 'UNSIGNED16')).toBe('0x0027');
    expect(toHex(1000, 'UNSIGNED32')).toBe('0x000003E8');
    expect(toHex(5, 'UNSIGNED8')).toBe('0x05');
    expect(toHex(5)).toBe('0x05');
  });

  it('shows negative values as the two’s complement the drive holds', () => {
    expect(toHex(-1, 'INTEGER16')).toBe('0xFFFF');
    expect(toHex(-1000, 'INTEGER32')).toBe('0xFFFFFC18');
    expect(toHex(-2, 'INTEGER8')).toBe('0xFE');
  });

  it('does not pretend a fraction has a hex form', () => {
    expect(toHex(1.5, 'REAL32')).toBe('—');
  });
});

describe('parseNumberInput', () => {
  it('reads hex in the forms people type', () => {
    for (const t of ['3E8', '0x3E8', '3e8h', '0000_03E8']) {
      expect(parseNumberInput(t, 'hex', 'UNSIGNED32')).toEqual({ ok: true, value: 1000 });
    }
  });

  it('reads a hex value with the top bit set as negative for signed types', () => {
    expect(parseNumberInput('FFFF', 'hex', 'INTEGER16')).toEqual({ ok: true, value: -1 });
    expect(parseNumberInput('FFFF', 'hex', 'UNSIGNED16')).toEqual({ ok: true, value: 65535 });
  });

  it('accepts 0x-prefixed input in decimal mode', () => {
    expect(parseNumberInput('0x10', 'dec', 'UNSIGNED8')).toEqual({ ok: true, value: 16 });
  });

  it('refuses values outside the data type', () => {
    const r = parseNumberInput('256', 'dec', 'UNSIGNED8');
    expect(r.ok).toBe(false);
    if (!r.ok) expect(r.message).toContain('0..255');
    expect(parseNumberInput('-1', 'dec', 'UNSIGNED16').ok).toBe(false);
    expect(parseNumberInput('1FFFF', 'hex', 'UNSIGNED16').ok).toBe(false);
  });

  it('refuses garbage with a sentence', () => {
    const r = parseNumberInput('12a', 'dec', 'INTEGER32');
    expect(r.ok).toBe(false);
    if (!r.ok) expect(r.message).toContain('whole number');
    expect(parseNumberInput('', 'dec', 'INTEGER32').ok).toBe(false);
    expect(parseNumberInput('xyz', 'hex', 'INTEGER32').ok).toBe(false);
  });

  it('takes decimals for REAL types', () => {
    expect(parseNumberInput('1.25', 'dec', 'REAL32')).toEqual({ ok: true, value: 1.25 });
    expect(parseNumberInput('1.25', 'hex', 'REAL32').ok).toBe(false);
  });
});

describe('display helpers', () => {
  it('prints raw bytes in bus order', () => {
    expect(formatRawBytes('e8030000')).toBe('E8 03 00 00');
    expect(formatRawBytes('')).toBe('—');
  });

  it('prints engineering values with unit', () => {
    expect(formatEngineering(12.5, 'rpm')).toBe('12.500 rpm');
    expect(formatEngineering(3600, 'deg')).toBe('3600 deg');
    expect(formatEngineering(null, 'rpm')).toBe('—');
  });

  it('puts a read value back into the input box in the chosen mode', () => {
    expect(valueToInput(1000, 'hex', 'UNSIGNED32')).toBe('000003E8');
    expect(valueToInput(-1, 'hex', 'INTEGER16')).toBe('FFFF');
    expect(valueToInput(1000, 'dec', 'UNSIGNED32')).toBe('1000');
  });
});
