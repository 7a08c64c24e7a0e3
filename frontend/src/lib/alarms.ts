/**
 * Helpers of the Alarms page: EMCY times, the error register bits (CiA 301 §7.5.2.2, 1001h),
 * and the EMCY log newest first.
 */
import type { EmcyLogEntry } from '../api/types';

/** CiA 301 §7.5.2.2: the bits of the error register 1001h. */
export const ERROR_REGISTER_BITS: readonly string[] = [
  'generic',
  'current',
  'voltage',
  'temperature',
  'communication',
  'device profile',
  'reserved',
  'manufacturer',
];

export function errorRegisterText(register: number): string {
  if (!register) return 'none';
  const names: string[] = [];
  for (let b = 0; b < 8; b++) if (register & (1 << b)) names.push(ERROR_REGISTER_BITS[b] ?? `bit ${b}`);
  return names.join(', ');
}

/** Unix seconds -> "2025-11-02 14:03:07.123" local time; "—" without a time. */
export function formatEventTime(t: number | null | undefined): string {
  if (t === null || t === undefined || !Number.isFinite(t)) return '—';
  const d = new Date(t * 1000);
  const p = (n: number, w = 2) => String(n).padStart(w, '0');
  return `${d.getFullYear()}-${p(d.getMonth() + 1)}-${p(d.getDate())} ${p(d.getHours())}:${p(d.getMinutes())}:${p(d.getSeconds())}.${p(d.getMilliseconds(), 3)}`;
}

/** Newest first; entries without a time keep their order at the end. */
export function newestFirst(log: readonly EmcyLogEntry[]): EmcyLogEntry[] {
  return log
    .map((e, i) => ({ e, i }))
    .sort((a, b) => {
      const ta = a.e.time ?? -Infinity;
      const tb = b.e.time ?? -Infinity;
      return tb === ta ? b.i - a.i : tb - ta;
    })
    .map((x) => x.e);
}

/** EMCY 0000h is "error reset / no error" (CiA 301 table 21), not an alarm. */
export function isResetEntry(e: Pick<EmcyLogEntry, 'code'>): boolean {
  return e.code === 0;
}
