import { describe, expect, it } from 'vitest';
import type { HomingRun, HomingStatus } from '../api/types';
import { decodeHoming, endFromMotion, formatDuration, homingShown, newerHoming, outcomeOfMotion, parseTimeout, signalLabel } from './homing';

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


function run(over: Partial<HomingRun> = {}): HomingRun {
  return {
    id: 7,
    method: 1,
    active: true,
    outcome: 'running',
    message: '',
    watched: true,
    started_at: 1000,
    elapsed_s: 3,
    phase: 'in progress',
    estimate_s: 13354,
    estimate: null,
    basis: "travel 707788 from the simulated twin's limit switches",
    travel: 707788,
    speed_switch: 3000,
    speed_zero: 10,
    acceleration: 40960,
    timeout_s: 3600,
    timeout_source: 'estimate',
    warnings: [],
    ...over,
  };
}

function status(r: HomingRun | null, state: HomingStatus['state'] = 'running'): HomingStatus {
  return {
    session: 'ctmm04x-4',
    method: 1,
    state,
    position: 0,
    statusword_bits: { target_reached: false, homing_attained: false, homing_error: false },
    message: '',
    run: r,
  };
}

describe('the end of a homing run (the panel never stays on running)', () => {
  it('takes the end from the motion that carried the run', () => {
    const ended = endFromMotion(run(), { kind: 'homing', active: false, state: 'deadman', message: "no heartbeat from client 'A' for 260 ms" });
    expect(ended?.outcome).toBe('deadman');
    expect(ended?.active).toBe(false);
    expect(ended?.message).toContain('heartbeat');
    expect(outcomeOfMotion('timeout')).toBe('timeout');
    expect(outcomeOfMotion('done')).toBe('attained');
    expect(outcomeOfMotion('stopped')).toBe('stopped');
    expect(outcomeOfMotion('replaced')).toBe('interrupted');
  });

  it('leaves the run alone for another motion, a running one, or an unwatched run', () => {
    expect(endFromMotion(run(), { kind: 'jog', active: false, state: 'halted', message: '' })).toBeNull();
    expect(endFromMotion(run(), { kind: 'homing', active: true, state: 'running', message: '' })).toBeNull();
    expect(endFromMotion(run({ watched: false }), { kind: 'homing', active: false, state: 'halted', message: '' })).toBeNull();
    expect(endFromMotion(run({ active: false, outcome: 'attained' }), { kind: 'homing', active: false, state: 'halted', message: '' })).toBeNull();
  });

  it('keeps an ended run against a late answer that shows it running', () => {
    const ended = status(run({ active: false, outcome: 'timeout' }), 'idle');
    const late = status(run());
    expect(newerHoming(ended, late)).toBe(ended);
    const older = status(run({ id: 6, started_at: 900 }));
    expect(newerHoming(ended, older)).toBe(ended);
    const next = status(run({ id: 8, started_at: 2000 }));
    expect(newerHoming(ended, next)).toBe(next);
    expect(newerHoming(null, late)).toBe(late);
  });

  it('shows the outcome of a run rather than the bits', () => {
    // CTMM04x after a cancel: bits 13/12/10 = 000 decode as running (003 §4-4-7).
    expect(homingShown(status(run({ active: false, outcome: 'deadman' })), 'running')).toEqual({ key: 'deadman', label: 'stopped by the dead-man' });
    expect(homingShown(status(run({ active: false, outcome: 'timeout' })), 'running').label).toBe('timed out');
    expect(homingShown(status(run({ active: false, outcome: 'control_lost' })), 'running').label).toBe('stopped: control lost');
    expect(homingShown(null, 'attained')).toEqual({ key: 'attained', label: 'attained' });
  });

  it('formats durations and reads the time-out field', () => {
    expect(formatDuration(2.5)).toBe('2.5 s');
    expect(formatDuration(42)).toBe('42 s');
    expect(formatDuration(200)).toBe('3 min 20 s');
    expect(formatDuration(13400)).toBe('3 h 43 min');
    expect(parseTimeout('')).toEqual({ value: null, error: null });
    expect(parseTimeout('90')).toEqual({ value: 90, error: null });
    expect(parseTimeout('0').error).not.toBeNull();
    expect(parseTimeout('x').error).not.toBeNull();
  });
});
