/**
 * The global stop (issue 48): which key stops every axis, and what the person is told after.
 *
 * The key is Escape. It is the stop key of machine-tool front ends (an operator reaches for
 * it without looking), no browser reserves it for itself while a page has the focus (Chrome
 * and Firefox use it only to leave full screen, cancel a page load or close their own
 * pop-ups), and it reaches the page from every element, inputs included. The keys the pages
 * use already (Space and Enter press the jog buttons, arrows and Tab move the focus) would
 * clash; a combination (Ctrl+...) is slower in a hurry, and many are taken by the browsers.
 * Escape also closes servodesk's dialogs: there it stops the axes too (a stop is never the
 * wrong thing to do).
 *
 * POST /motion/stop-all answers per session (docs/api.md "StopAll"); `stopSummary` turns it
 * into one notice: what was stopped, what failed and why, what is still being sent.
 */
import type { MotionStatus } from '../api/types';

/** The key, as `KeyboardEvent.key` names it, and as the tooltip and docs/ui.md write it. */
export const STOP_KEY = 'Escape';
export const STOP_KEY_LABEL = 'Esc';

/** True for a key press that is the global stop: Escape alone or with Shift, not a repeat
 * (holding the key must not send a stop every 30 ms), not with Ctrl / Alt / Meta (the
 * operating systems use those: Ctrl+Esc opens the Windows start menu, Alt+Esc switches
 * windows). */
export function isStopKey(e: Pick<KeyboardEvent, 'key' | 'repeat' | 'ctrlKey' | 'altKey' | 'metaKey'>): boolean {
  return e.key === STOP_KEY && !e.repeat && !e.ctrlKey && !e.altKey && !e.metaKey;
}

export interface StopAllItem {
  session: string;
  result: 'stopped' | 'failed' | 'pending';
  motion: MotionStatus | null;
  message: string | null;
  hint: string | null;
}

export interface StopAllResult {
  user: string;
  sessions: StopAllItem[];
  stopped: number;
  failed: number;
  pending: number;
}

export interface StopSummary {
  kind: 'info' | 'warning' | 'error';
  title: string;
  message: string;
  hint: string | null;
}

function axes(n: number): string {
  return n === 1 ? '1 axis' : `${n} axes`;
}

/** One notice for the answer of POST /motion/stop-all. */
export function stopSummary(r: StopAllResult): StopSummary {
  if (r.sessions.length === 0) {
    return {
      kind: 'warning',
      title: 'Stop all: you control no axis',
      message: 'Nothing was stopped: no open drive is under your control (STOP ALL stops only the axes you hold control of).',
      hint: "to stop an axis someone else controls, use Quick stop on that drive's Overview or Operation page: it always works",
    };
  }
  const stopped = r.sessions.filter((i) => i.result === 'stopped').map((i) => i.session);
  const failed = r.sessions.filter((i) => i.result === 'failed');
  const pending = r.sessions.filter((i) => i.result === 'pending');
  const parts: string[] = [];
  if (stopped.length) parts.push(`quick stop sent to ${stopped.join(', ')}`);
  for (const i of failed) parts.push(`${i.session} FAILED: ${i.message ?? 'no answer'}`);
  for (const i of pending) parts.push(`${i.session} not confirmed yet: ${i.message ?? 'still being sent'}`);
  if (failed.length === 0 && pending.length === 0) {
    return { kind: 'info', title: `Stop all: ${axes(stopped.length)} stopped`, message: `${parts.join('; ')}.`, hint: null };
  }
  return {
    kind: failed.length ? 'error' : 'warning',
    title: `Stop all: ${axes(failed.length + pending.length)} of ${r.sessions.length} not confirmed`,
    message: `${parts.join('; ')}.`,
    hint: failed.find((i) => i.hint)?.hint ?? pending.find((i) => i.hint)?.hint ?? 'watch the axes; stop them at the machine if they keep moving',
  };
}
