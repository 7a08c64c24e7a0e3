import { describe, expect, it } from 'vitest';
import type { ErrorInfo } from '../api/types';
import { codeInObject, findError } from './codes';
import { checkWrite } from './validate';

const ACC = { index: 0x6083, name: 'Profile acceleration', data_type: 'UNSIGNED32', access: 'rw', min: 0, max: 50000, values: null, raw_unit: 'ms' };

describe('checkWrite', () => {
  it('checks the profile limits with the unit', () => {
    const r = checkWrite(ACC, '60000', 'dec');
    expect(r.ok).toBe(false);
    if (!r.ok) expect(r.message).toBe('60000 ms is above the maximum 50000 ms');
    expect(checkWrite(ACC, '1500', 'dec')).toMatchObject({ ok: true, body: { value: 1500 } });
  });
  it('takes hex entry', () => {
    expect(checkWrite(ACC, '5DC', 'hex')).toMatchObject({ ok: true, body: { value: 1500 } });
    expect(checkWrite(ACC, '5DG', 'hex').ok).toBe(false);
  });
  it('checks the type range', () => {
    const r = checkWrite({ ...ACC, min: null, max: null }, '-5', 'dec');
    expect(r.ok).toBe(false);
    if (!r.ok) expect(r.message).toContain('outside UNSIGNED32');
  });
  it('refuses read-only objects', () => {
    expect(checkWrite({ ...ACC, access: 'ro' }, '1', 'dec').ok).toBe(false);
  });
  it('refuses values outside a closed enumeration, notes others', () => {
    const modes = { ...ACC, index: 0x6060, data_type: 'INTEGER8', min: null, max: null, values: { '1': 'Profile position', '3': 'Profile velocity' } };
    expect(checkWrite(modes, '2', 'dec').ok).toBe(false);
    expect(checkWrite(modes, '3', 'dec')).toMatchObject({ ok: true, note: null });
    const open = { ...modes, index: 0x605a };
    expect(checkWrite(open, '2', 'dec')).toMatchObject({ ok: true, note: '2 is not one of the documented values' });
  });
});

describe('codes', () => {
  const errors: ErrorInfo[] = [
    { table: 'error_code', code: 0x8611, code_hex: '0x8611', display: null, name: 'Following error', kind: 'fault', cause: 'too far behind', remedy: 'raise the window', section: null },
    { table: 'sdo_abort', code: 0x06090030, code_hex: '0x06090030', display: null, name: 'Value range exceeded', kind: 'abort', cause: 'c', remedy: 'r', section: null },
  ];
  it('finds a protocol code in its own table', () => {
    expect(findError(errors, 0x06090030, 'sdo')?.name).toBe('Value range exceeded');
    expect(findError(errors, 0x8611, 'sdo')).toBeNull();
  });
  it('explains codes held in objects', () => {
    expect(codeInObject({ index: 0x603f, name: 'Error code' }, 0x8611, errors)?.remedy).toBe('raise the window');
    expect(codeInObject({ index: 0x603f, name: 'Error code' }, 0, errors)).toBeNull();
    expect(codeInObject({ index: 0x6081, name: 'Profile velocity' }, 0x8611, errors)).toBeNull();
  });
});
