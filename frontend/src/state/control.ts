/**
 * Control of the drives as this tab sees it, shared by the header's control indicator and
 * every page that changes a drive (docs/api.md "Control and motion as built").
 *
 * Sources: GET /control (sent with the tab's token: the server says `you`), the `control`
 * messages every socket gets (holder, bound, orphaned), the answers to this tab's take /
 * release, and the socket's bind answers. Taking control stores the answer's token
 * (lib/controlToken: one per tab, in sessionStorage) and binds the socket at once; releasing
 * the last session clears it. When a message says someone else holds a session this tab
 * thought it held, GET /control confirms before the token forgets it (a message may be older
 * than this tab's own take). `safe_state` becomes a notice on every tab.
 */
import { useEffect } from 'react';
import { ApiError, operationApi } from '../api/client';
import type { Control, ControlProtection } from '../api/types';
import { tabClientId } from '../lib/backupClientId';
import { type ControlView, emptyView, holdsControl } from '../lib/control';
import { tabControl } from '../lib/controlToken';
import { Fresh } from '../lib/fresh';
import type { MotionSettingsMessage, SafeStateMessage } from '../ws/messages';
import { notify } from './notify';
import { Observable, useObservable } from './observable';
import { socket } from './store';

interface ServerControl {
  known: boolean;
  owner: string | null;
  user: string | null;
  since: number | null;
  bound: boolean;
  orphaned: boolean;
  protection: ControlProtection | null;
}

interface Entry {
  server: ServerControl;
  obs: Observable<ControlView>;
  fresh: Fresh<Control>;
}

const entries = new Map<string, Entry>();
/** Counts this tab's takes per session: a check sent before a take must not undo it. */
const takes = new Map<string, number>();

function me(): string {
  return tabClientId();
}

function derive(sid: string, server: ServerControl): ControlView {
  return {
    ...emptyView(sid, socket.bindStatus(sid)),
    ...server,
    you: holdsControl(server.known, server.owner, me(), tabControl.holds(sid)),
  };
}

function entry(sid: string): Entry {
  let e = entries.get(sid);
  if (!e) {
    const server: ServerControl = { known: false, owner: null, user: null, since: null, bound: false, orphaned: false, protection: null };
    const obs = new Observable<ControlView>(derive(sid, server));
    const created: Entry = {
      server,
      obs,
      fresh: new Fresh<Control>((c) => applyControl(sid, c)),
    };
    entries.set(sid, created);
    e = created;
  }
  return e;
}

function refresh(sid: string): void {
  const e = entry(sid);
  e.obs.set(derive(sid, e.server));
}

/** A full Control (GET or the answer to take / release): its `you` is the server's word. */
function applyControl(sid: string, c: Control): void {
  const e = entry(sid);
  // The messages carry no `protection`: the last one read stays (it is the drive's, not the holder's).
  e.server = {
    known: true,
    owner: c.owner,
    user: c.user ?? null,
    since: c.since,
    bound: c.bound ?? false,
    orphaned: c.orphaned ?? false,
    protection: c.protection === undefined ? e.server.protection : c.protection,
  };
  if (c.you && c.token) tabControl.took(sid, c.token);
  refresh(sid);
}

export function controlView(sid: string): Observable<ControlView> {
  return entry(sid).obs;
}

/** Control of `sid` as this tab sees it; read from the server the first time it is asked. */
export function useControl(sid: string): ControlView {
  useEffect(() => {
    if (!entry(sid).server.known && !reading.has(sid)) loadControl(sid);
  }, [sid]);
  return useObservable(entry(sid).obs);
}

const reading = new Set<string>();

/**
 * Read who holds control, with this tab's token so that the server says whether it is this
 * tab. Shown unless something newer arrived meanwhile (lib/fresh); and when the server does
 * not count this tab as the holder of a session the token lists, the token forgets it
 * (unless this tab took it again after the read was sent): after a message naming another
 * holder, a refused bind, a reconnect, or a reload after the server's grace.
 */
export function loadControl(sid: string): void {
  const taken = takes.get(sid) ?? 0;
  let answer: Control | null = null;
  reading.add(sid);
  entry(sid)
    .fresh.read(async () => {
      answer = await operationApi.control(sid);
      return answer;
    })
    .then(
      () => {
        const c = answer as Control | null;
        if (c && !c.you && tabControl.holds(sid) && (takes.get(sid) ?? 0) === taken) forgetControl(sid);
      },
      (e: unknown) => {
        // The session is gone (closed elsewhere): nobody holds it, the token forgets it.
        if (e instanceof ApiError && e.status === 404 && tabControl.holds(sid)) forgetControl(sid);
        // Otherwise the server did not answer: keep what is shown; the next read decides.
      },
    )
    .finally(() => reading.delete(sid));
}

/** This tab no longer holds `sid` (released, closed, taken over, lapsed). */
export function forgetControl(sid: string): void {
  tabControl.dropped(sid);
  socket.unbind(sid);
  refresh(sid);
}

/**
 * Take control of `sid` (force: take it over from its holder, confirmed by the person). The
 * tab's token goes with the request, so the answer is the same token for every session;
 * the socket binds at once as the drive's dead-man. Throws the ApiError of a refusal.
 */
export async function takeControl(sid: string, force = false): Promise<ControlView> {
  const c = await operationApi.setControl(sid, force ? 'force_take' : 'take', force);
  takes.set(sid, (takes.get(sid) ?? 0) + 1);
  if (c.token) {
    tabControl.took(sid, c.token);
    socket.bind(sid, c.token);
  }
  entry(sid).fresh.set(c);
  return entry(sid).obs.get();
}

/** Release control of `sid`: the server stops its motion and disables the drive. */
export async function releaseControl(sid: string): Promise<void> {
  try {
    const c = await operationApi.setControl(sid, 'release');
    forgetControl(sid);
    entry(sid).fresh.set(c);
  } catch (e) {
    loadControl(sid);
    throw e;
  }
}

function safeStateNotice(m: SafeStateMessage): void {
  const mine = m.client !== null && m.client === me();
  const who = mine ? 'this tab' : m.client ? `client ${m.client}` : 'its holder';
  notify({
    kind: m.ok ? 'warning' : 'error',
    title: m.ok ? `${m.session}: the drive was stopped and disabled` : `${m.session}: the drive could not be made safe`,
    message: `${m.ok ? `The drive was stopped and disabled because ${m.reason}${m.state ? `; it is now in ${m.state}` : ''}.` : `${m.message}.`} Control was held by ${who}.`,
    detail: null,
    hint: m.ok
      ? 'check the axis; whoever holds control now must switch the servo on again before the next motion'
      : 'the server could not disable the drive: stop it at the machine (QUICK STOP or the emergency stop) and check the link',
  }, 30_000);
}

/** A motion's settings that could not be put back: the user must know they changed. */
function motionSettingsNotice(m: MotionSettingsMessage): void {
  if (m.kept.length === 0) return;
  notify({
    kind: 'warning',
    title: `${m.session}: settings the motion changed were not put back`,
    message: m.kept.join('; '),
    detail: null,
    hint: 'they stay marked as written since the last save: check them on the Parameters page before you save',
  }, 30_000);
}

let started = false;

/** Register the socket handlers once (the socket itself is started by the shared store). */
export function startControlStore(): void {
  if (started) return;
  started = true;
  socket.on('control', (m) => {
    const e = entry(m.session);
    e.fresh.set({
      session: m.session,
      owner: m.owner,
      user: m.user ?? null,
      since: m.since,
      // A message never carries the token: who holds it is decided by derive().
      you: false,
      bound: m.bound ?? false,
      orphaned: m.orphaned ?? false,
    });
    if (tabControl.holds(m.session) && m.owner !== me()) loadControl(m.session);
  });
  socket.onBind((sid, status) => {
    refresh(sid);
    if (status.state === 'refused') loadControl(sid);
  });
  socket.on('safe_state', safeStateNotice);
  socket.on('motion_settings', motionSettingsNotice);
  tabControl.subscribe(() => {
    for (const sid of entries.keys()) refresh(sid);
  });
  // After a reconnect the messages sent meanwhile are lost: read again what is shown.
  socket.onStatus((s) => {
    if (s.status !== 'open') return;
    for (const sid of entries.keys()) loadControl(sid);
  });
  // A reload keeps the token: check it still holds what it lists (the grace may be over).
  for (const sid of tabControl.sessions()) loadControl(sid);
}
