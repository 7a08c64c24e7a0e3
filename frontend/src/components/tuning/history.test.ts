import { describe, expect, it } from 'vitest';
import { bandwidthText, durationText, marginsText, statusText } from './history';

describe('tuning history rows', () => {
  const m = { phase_margin_deg: 45.234, gain_margin_db: 8.06, bandwidth_hz: 120.4, crossover_hz: 45.31 };
  it('say the margins and the bandwidth with their units', () => {
    expect(marginsText(m)).toBe('PM 45.2 °, GM 8.06 dB');
    expect(bandwidthText(m)).toBe('120 Hz (crossover 45.3 Hz)');
    expect(marginsText(null)).toBe('—');
    expect(bandwidthText({ ...m, bandwidth_hz: null })).toBe('—');
    expect(bandwidthText({ ...m, crossover_hz: null })).toBe('120 Hz');
  });
  it('say how a tuning ended and whether its gains stayed', () => {
    expect(statusText({ status: 'done', applied: true })).toBe('finished, gains applied');
    expect(statusText({ status: 'stopped', applied: false })).toBe('stopped, gains not applied');
    expect(statusText({ status: 'failed', applied: false })).toBe('failed, gains not applied');
  });
  it('say how long it ran', () => {
    expect(durationText({ started: 100, ended: 148 })).toBe('48 s');
    expect(durationText({ started: 0, ended: 125 })).toBe('2 min 5 s');
  });
});
