import { describe, expect, it } from 'vitest';
import type { EmcyLogEntry } from '../api/types';
import { errorRegisterText, formatEventTime, isResetEntry, newestFirst } from './alarms';

function e(code: number, time: number | null): EmcyLogEntry {
  return { code, code_hex: `0x${code.toString(16)}`, time, name: null, cause: null, remedy: null, register: 0 };
}

describe('alarms helpers', () => {
  it('names the error register bits (CiA 301 1001h)', () => {
    expect(errorRegisterText(0)).toBe('none');
    expect(errorRegisterText(0x21)).toBe('generic, device profile');
    expect(errorRegisterText(0x81)).toBe('generic, manufacturer');
  });

  it('lists the EMCY log newest first, entries without time last', () => {
    const out = newestFirst([e(1, 10), e(2, null), e(3, 30), e(4, 20)]);
    expect(out.map((x) => x.code)).toEqual([3, 4, 1, 2]);
  });

  it('formats times with milliseconds and marks EMCY 0000h as the reset entry', () => {
    expect(formatEventTime(null)).toBe('—');
    expect(formatEventTime(0.5)).toMatch(/^\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2}\.500$/);
    expect(isResetEntry({ code: 0 })).toBe(true);
    expect(isResetEntry({ code: 0x8611 })).toBe(false);
  });
});
