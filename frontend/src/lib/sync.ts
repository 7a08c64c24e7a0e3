/**
 * Synchronisation of cyclic data (docs/pdo.md "Synchronisation"): FreeRun, the drive's own
 * cycle, or DC, its SYNC0 event from the EtherCAT distributed clocks at the exchange's period.
 * The server lists what a session offers (`sync_modes`) and the SYNC0 cycles the drive takes
 * (`dc_cycle_ns`: min, max, step from the profile; HIWIN 000 §2.5: 250 µs steps, 250 µs to 4 ms).
 */

export type SyncMode = 'freerun' | 'dc';

/** Why `periodMs` is no SYNC0 cycle of the drive (null: it is one). */
export function dcCycleProblem(periodMs: number, cycles: readonly number[] | null | undefined): string | null {
  if (!cycles || cycles.length !== 3) return 'the drive names no SYNC0 cycle';
  const [low, high, step] = cycles as [number, number, number];
  const ns = Math.round(periodMs * 1e6);
  const ms = (v: number) => `${+(v / 1e6).toFixed(4)} ms`;
  if (ns < low || ns > high || ns % step !== 0) {
    return `SYNC0 takes ${ms(step)} steps from ${ms(low)} to ${ms(high)}`;
  }
  return null;
}

/** What the status line says of the exchange's clock. */
export function syncText(mode: string | null | undefined, periodMs: number | null | undefined): string | null {
  if (!periodMs) return null;
  return mode === 'dc' ? `DC SYNC0 every ${periodMs} ms` : `SYNC every ${periodMs} ms`;
}
