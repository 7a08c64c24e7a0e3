/**
 * STOP ALL in the header, on every page (issue 48): one click or the Escape key quick-stops
 * every axis this user controls (state/globalStop.ts). Never disabled and never asks: a
 * second press while the first is on its way sends another stop.
 */
import { useEffect } from 'react';
import { STOP_KEY_LABEL } from '../lib/globalStop';
import { installStopKey, stopAll, stopsInFlight } from '../state/globalStop';
import { useObservable } from '../state/observable';
import './globalStop.css';

export const GLOBAL_STOP_TITLE =
  `Stop all (${STOP_KEY_LABEL} on any page): quick stop to every axis you hold control of, in any tab, all at once. ` +
  'It needs no control and is never refused. An axis someone else controls: Quick stop on its own page.';

export function GlobalStopButton() {
  const inFlight = useObservable(stopsInFlight);
  useEffect(() => installStopKey(), []);
  return (
    <button
      type="button"
      className="global-stop"
      data-testid="global-stop"
      data-busy={inFlight > 0 ? 'true' : 'false'}
      title={GLOBAL_STOP_TITLE}
      aria-label="Stop all"
      aria-keyshortcuts="Escape"
      onClick={() => void stopAll()}
    >
      <span className="global-stop-long">{inFlight > 0 ? 'STOPPING…' : 'STOP ALL'}</span>
      <span className="global-stop-short">STOP</span>
      <kbd className="global-stop-key">{STOP_KEY_LABEL}</kbd>
    </button>
  );
}
