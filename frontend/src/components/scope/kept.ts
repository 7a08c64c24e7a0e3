/**
 * The pure part of the kept captures (issue 49, docs/scope.md "Kept captures"): what the Keep
 * form refuses before asking the server, and how the list says a capture's channels, their
 * units and sample periods. The server checks the same (api/schemas_scope.py CaptureKeep):
 * the page only says it earlier, in the same words.
 */
import type { CaptureChannelInfo, CaptureInfo } from '../../api/scope';
import { hz, num, secs } from './format';

/** The longest title and note the server takes (CaptureKeep). */
export const MAX_TITLE = 200;
export const MAX_NOTE = 4000;

/** Why a title cannot be kept (null: it can). */
export function titleProblem(title: string): string | null {
  if (title.trim() === '') return 'Give the capture a title: it names the capture in the list and in the report.';
  if (title.length > MAX_TITLE) return `The title is ${title.length} characters long; at most ${MAX_TITLE}.`;
  if (title.includes('\0')) return 'The title holds a NUL character.';
  return null;
}

/** Why a note cannot be kept (null: it can). */
export function noteProblem(note: string): string | null {
  if (note.length > MAX_NOTE) return `The note is ${note.length} characters long; at most ${MAX_NOTE}.`;
  if (note.includes('\0')) return 'The note holds a NUL character.';
  return null;
}

/** Why a deletion's reason is refused (null: it is fine); the audit log keeps it. */
export function reasonProblem(reason: string): string | null {
  if (reason.trim() === '') return 'Say why the capture is deleted: the audit log keeps the reason.';
  if (reason.length > 2000) return `The reason is ${reason.length} characters long; at most 2000.`;
  return null;
}

/** A sample period with its rate: "1 ms (1 kHz)"; "—" when the channel has under 2 samples. */
export function periodText(period: number | null | undefined): string {
  if (period === null || period === undefined || !Number.isFinite(period) || period <= 0) return '—';
  return `${secs(period)} (${hz(1 / period)})`;
}

/** A channel's units as the scope shows them: "rev (raw inc, × 7.629e-6)". */
export function unitText(c: Pick<CaptureChannelInfo, 'unit' | 'raw_unit' | 'scale'>): string {
  const eng = c.unit || c.raw_unit || 'raw';
  if (!c.raw_unit || (c.scale === 1 && c.unit === c.raw_unit)) return eng;
  return `${eng} (raw ${c.raw_unit}, × ${num(c.scale, 4)})`;
}

/** One line per capture's channels for the list: "Position actual value [rev], Velocity …". */
export function channelsText(chs: readonly Pick<CaptureChannelInfo, 'name' | 'unit' | 'raw_unit'>[]): string {
  return chs.map((c) => `${c.name} [${c.unit || c.raw_unit || 'raw'}]`).join(', ');
}

/** The sample periods of a capture: one text when all channels share it, else the range. */
export function capturePeriod(chs: readonly Pick<CaptureChannelInfo, 'period_s'>[]): string {
  const ps = chs.map((c) => c.period_s).filter((p): p is number => p !== null && p !== undefined && Number.isFinite(p) && p > 0);
  if (ps.length === 0) return '—';
  const lo = Math.min(...ps);
  const hi = Math.max(...ps);
  return Math.abs(hi - lo) <= lo * 1e-3 ? periodText(lo) : `${secs(lo)} … ${secs(hi)}`;
}

/** When a capture was kept, in the browser's local time, with seconds. */
export function keptWhen(c: Pick<CaptureInfo, 'created'>): string {
  return new Date(c.created * 1000).toLocaleString(undefined, { hour12: false });
}
