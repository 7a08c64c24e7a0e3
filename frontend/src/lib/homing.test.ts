import { describe, expect, it } from 'vitest';
import { decodeHoming, signalLabel } from './homing';

describe('decodeHoming (CiA 402-2 §6.8.1, bits 13/12/10)', () => {
  it('is idle outside homing mode whatever the bits say', () => {
    expect(decodeHoming(0x1437, 1)).toBe('idle');
    expect(decodeHoming(0x1437, null)).toBe('idle');
  });

  it('decodes the homing table', () => {
    expect(decodeHoming(0x0037, 6)).toBe('running'); // 13=0 12=0 10=0
    expect(decodeHoming(0x0437, 6)).toBe('idle'); // interrupted or not started
    expect(decodeHoming(0x1037, 6)).toBe('running'); // attained, target not yet reached
    expect(decodeHoming(0x1437, 6)).toBe('attained');
    expect(decodeHoming(0x2037, 6)).toBe('error');
    expect(decodeHoming(0x3437, 6)).toBe('error');
  });

  it('names the signals a method uses', () => {
    expect(signalLabel('home_switch')).toBe('Home switch');
    expect(signalLabel('index')).toBe('Index pulse');
    expect(signalLabel('some_new_signal')).toBe('some new signal');
  });
});
