/**
 * The session lock on inactivity (IEC 62443-4-2 CR 2.5; docs/security.md "Sessions").
 *
 * The server ends a login session after `idle_timeout_s` without an HTTP request, but an open
 * tab polls (the PDO page, the operation store, homing), so a tab left open on a plant PC would
 * never be locked. This lock counts the person, not the tab: after `idle_timeout_s` without a
 * key, pointer, wheel or touch input the UI logs out. The server then ends the session and
 * closes its sockets (an axis held by this user stops, as on any lost operator), and the login
 * page says why. The single-user mode (loopback, no login) has nothing to lock.
 */
import { me, loginReason, type Me } from '../api/auth';

/** Input events that count as the person being there. */
const INPUT_EVENTS = ['pointerdown', 'keydown', 'wheel', 'touchstart'] as const;
/** How often the lock looks (ms): it fires at most this long after the time-out. */
const CHECK_MS = 1000;

/** Whether `idleS` seconds have passed since the last input (a time-out of 0 never locks). */
export function idleExpired(lastInputMs: number, nowMs: number, idleS: number): boolean {
  return idleS > 0 && nowMs - lastInputMs >= idleS * 1000;
}

/** The text the login page shows after the lock. */
export function lockReason(idleS: number): string {
  const minutes = idleS / 60;
  const span = minutes >= 1 ? `${Math.round(minutes)} min` : `${Math.round(idleS)} s`;
  return `logged out after ${span} without input (session lock); log in again`;
}

/** Start the lock for the logged-in user `who`; returns a function that stops it. */
export function startIdleLock(who: Me, logout: () => Promise<void>): () => void {
  if (who.mode !== 'login' || who.idle_timeout_s <= 0) return () => undefined;
  let last = Date.now();
  const seen = () => {
    last = Date.now();
  };
  for (const e of INPUT_EVENTS) window.addEventListener(e, seen, { capture: true, passive: true });
  const timer = window.setInterval(() => {
    if (!idleExpired(last, Date.now(), who.idle_timeout_s)) return;
    stop();
    void logout().finally(() => {
      loginReason.set(lockReason(who.idle_timeout_s));
      me.set(null);
    });
  }, CHECK_MS);
  function stop() {
    window.clearInterval(timer);
    for (const e of INPUT_EVENTS) window.removeEventListener(e, seen, { capture: true });
  }
  return stop;
}
