/**
 * The global stop (issue 48): the header's STOP ALL and the Escape key both call `stopAll`.
 *
 * First this tab's own dead-man heartbeats end, for every drive (no request needed: if the
 * stop request cannot get through, the server's dead-man stops the motion this tab started
 * within SERVODESK_DEADMAN_MS). Then one POST /motion/stop-all quick-stops every axis this
 * user controls, from any tab (docs/api.md "StopAll"); the server sends the stops to all
 * drives at once, so a slow drive does not hold up the others. Nothing waits for an earlier
 * press: each press sends its own request, and the button is never disabled.
 */
import { postStopAll } from '../api/stopAll';
import { setMotion, stopHeartbeat } from '../components/operation/operationStore';
import { isStopKey, stopSummary } from '../lib/globalStop';
import { tabControl } from '../lib/controlToken';
import { notify, notifyError } from './notify';
import { Observable } from './observable';
import { sessions } from './store';

/** Stop requests on their way (the button says "Stopping…" meanwhile; it stays enabled). */
export const stopsInFlight = new Observable<number>(0);

export async function stopAll(): Promise<void> {
  const sids = new Set<string>([...tabControl.sessions(), ...(sessions.get() ?? []).map((s) => s.id)]);
  for (const sid of sids) stopHeartbeat(sid);
  stopsInFlight.update((n) => n + 1);
  try {
    const r = await postStopAll();
    for (const item of r.sessions) {
      if (item.motion) setMotion(item.session, item.motion);
    }
    const s = stopSummary(r);
    notify({ kind: s.kind, title: s.title, message: s.message, detail: null, hint: s.hint }, s.kind === 'info' ? 6_000 : 30_000);
  } catch (e) {
    notifyError(e);
  } finally {
    stopsInFlight.update((n) => Math.max(0, n - 1));
  }
}

let installed = 0;

function onKey(e: KeyboardEvent): void {
  if (isStopKey(e)) void stopAll();
}

/**
 * Listen for the stop key on the whole window, in the capture phase: before any page's own
 * handler, so no element can swallow it (default actions such as closing a dialog still
 * happen). Returns the uninstall; installed once however many callers.
 */
export function installStopKey(): () => void {
  if (installed++ === 0) window.addEventListener('keydown', onKey, true);
  return () => {
    if (--installed === 0) window.removeEventListener('keydown', onKey, true);
  };
}
