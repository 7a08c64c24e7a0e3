import { describe, expect, it, vi } from 'vitest';
import type { HomingRun, HomingStatus, MotionStatus } from '../../api/types';

vi.mock('../../state/store', () => ({ socket: { on: vi.fn(), heartbeat: vi.fn() } }));
vi.mock('../../api/client', () => ({ operationApi: { motion: vi.fn(), control: vi.fn() } }));
vi.mock('../../lib/backupClientId', () => ({ tabClientId: () => 'me' }));

const { operationLive, setHoming, setMotion } = await import('./operationStore');

function run(over: Partial<HomingRun> = {}): HomingRun {
  return {
    id: 1,
    method: 1,
    active: true,
    outcome: 'running',
    message: '',
    watched: true,
    started_at: 1000,
    elapsed_s: 0.1,
    phase: 'in progress',
    estimate_s: 13354,
    estimate: null,
    basis: 'test',
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

function homing(sid: string, r: HomingRun): HomingStatus {
  return {
    session: sid,
    method: 1,
    state: 'running',
    position: 0,
    statusword_bits: { target_reached: false, homing_attained: false, homing_error: false },
    message: 'homing in progress',
    run: r,
  };
}

function motion(sid: string, active: boolean, state: string, message = '', kind: MotionStatus['kind'] = 'homing'): MotionStatus {
  return { session: sid, active, kind, owner: 'me', mode: 6, target: null, state, message };
}

describe('the homing run follows the motion that carries it', () => {
  it('ends the run shown when its motion ends, even without the homing message', () => {
    const sid = 'ctmm04x-4';
    setHoming(sid, homing(sid, run()));
    setMotion(sid, motion(sid, true, 'running', 'homing method 1'));
    // The dead-man stops the motion; the run's own last message is lost.
    setMotion(sid, motion(sid, false, 'deadman', "no heartbeat from client 'me' for 251 ms"));
    const r = operationLive(sid).get().homing?.run;
    expect(r?.active).toBe(false);
    expect(r?.outcome).toBe('deadman');
    expect(r?.message).toContain('heartbeat');
  });

  it('is not ended by the late end of the motion before it', () => {
    const sid = 'ctmm04x-5';
    setHoming(sid, homing(sid, run({ id: 1 })));
    setMotion(sid, motion(sid, true, 'running'));
    // A second run starts: its answer comes first, then the first motion's "replaced" end.
    setHoming(sid, homing(sid, run({ id: 2, started_at: 2000 })));
    setMotion(sid, motion(sid, false, 'replaced', 'replaced by homing'));
    expect(operationLive(sid).get().homing?.run?.active).toBe(true);
    setMotion(sid, motion(sid, true, 'running'));
    setMotion(sid, motion(sid, false, 'timeout', 'homing timed out after 1 s'));
    expect(operationLive(sid).get().homing?.run?.outcome).toBe('timeout');
  });

  it('keeps an end it has against a late answer that shows the run running', () => {
    const sid = 'ctmm04x-6';
    setHoming(sid, homing(sid, run({ id: 3, active: false, outcome: 'attained', message: 'homing attained at 0' })));
    setHoming(sid, homing(sid, run({ id: 3 })));
    expect(operationLive(sid).get().homing?.run?.outcome).toBe('attained');
  });
});
