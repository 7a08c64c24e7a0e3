import { describe, expect, it } from 'vitest';
import { decodeState, modeName, statuswordRows } from './cia402';

describe('decodeState', () => {
  it('decodes the CiA 402 table 30 patterns', () => {
    expect(decodeState(0x0250)).toBe('Switch on disabled');
    expect(decodeState(0x0231)).toBe('Ready to switch on');
    expect(decodeState(0x0233)).toBe('Switched on');
    expect(decodeState(0x0237)).toBe('Operation enabled');
    expect(decodeState(0x0217)).toBe('Quick stop active');
    expect(decodeState(0x0218)).toBe('Fault');
    expect(decodeState(0x021f)).toBe('Fault reaction active');
    expect(decodeState(0x0000)).toBe('Not ready to switch on');
  });
});

describe('statuswordRows', () => {
  it('gives 16 rows, bit 15 first, with set taken from the word', () => {
    const rows = statuswordRows(0x1237);
    expect(rows).toHaveLength(16);
    expect(rows[0]?.bit).toBe(15);
    expect(rows.find((r) => r.bit === 2)?.set).toBe(true);
    expect(rows.find((r) => r.bit === 3)?.set).toBe(false);
    expect(rows.find((r) => r.bit === 12)?.set).toBe(true);
  });

  it('prefers the mode-specific names the drive reports', () => {
    const rows = statuswordRows(0x1000, [{ bit: 12, name: 'Set-point acknowledge' }]);
    const b12 = rows.find((r) => r.bit === 12);
    expect(b12?.name).toBe('Set-point acknowledge');
    expect(b12?.fromDrive).toBe(true);
    expect(rows.find((r) => r.bit === 13)?.name).toBe('Operation mode specific');
  });
});

describe('modeName', () => {
  it('names standard modes and prefers the drive’s own name', () => {
    expect(modeName(1)).toBe('Profile position (pp)');
    expect(modeName(-3)).toBe('Manufacturer specific');
    expect(modeName(3, 'Profile velocity')).toBe('Profile velocity');
    expect(modeName(null)).toBe('—');
  });
});
