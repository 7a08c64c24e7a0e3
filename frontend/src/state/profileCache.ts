/**
 * Profiles with their full object list (GET /profiles/{id}), loaded once per profile and
 * shared by the Parameters and Object dictionary pages (lecsn-t's answer is ~1.3 MB), and the
 * open session's SessionInfo kept fresh for the dirty markers.
 *
 * A page of a session asks for the session's profile (`useSessionProfile`): the family's,
 * unless the drive's encoder (608Fh) differs from the one the profile's deg and rpm scales are
 * written for; then the session's own copy with those scales rescaled (GET
 * /sessions/{sid}/profile), so that 6064h shows the axis's own degrees.
 */
import { useCallback, useEffect, useRef, useState } from 'react';
import { api } from '../api/client';
import type { ProfileDetail, SessionInfo } from '../api/types';
import { useObservable } from './observable';
import { sessions } from './store';

const cache = new Map<string, Promise<ProfileDetail>>();

export function loadProfile(id: string): Promise<ProfileDetail> {
  let p = cache.get(id);
  if (!p) {
    p = api.profile(id);
    cache.set(id, p);
    // A failed load is not cached: the next page visit tries again.
    p.catch(() => cache.delete(id));
  }
  return p;
}

/** The cache key of a session's profile: its family's id, or its own when rescaled. */
export function sessionProfileKey(info: SessionInfo): string {
  const enc = info.encoder;
  return enc?.rescaled ? `session:${info.id}:${enc.counts_per_rev}` : info.profile_id;
}

/** The profile the pages of session `info` show (see the module note). */
export function loadSessionProfile(info: SessionInfo): Promise<ProfileDetail> {
  const key = sessionProfileKey(info);
  if (key === info.profile_id) return loadProfile(key);
  let p = cache.get(key);
  if (!p) {
    p = api.sessionProfile(info.id);
    cache.set(key, p);
    p.catch(() => cache.delete(key));
  }
  return p;
}

export interface ProfileLoad {
  profile: ProfileDetail | null;
  error: unknown;
}

/** The profile for the pages of a session: its family's, or its own when its units are rescaled. */
export function useSessionProfile(info: SessionInfo | null): ProfileLoad {
  const key = info ? sessionProfileKey(info) : null;
  const [state, setState] = useState<ProfileLoad>({ profile: null, error: null });
  // `info` changes with every push (dirty markers); the load follows the key alone.
  const latest = useRef(info);
  latest.current = info;
  useEffect(() => {
    const current = latest.current;
    if (!key || !current) return;
    let live = true;
    setState({ profile: null, error: null });
    loadSessionProfile(current).then(
      (profile) => live && setState({ profile, error: null }),
      (error: unknown) => live && setState({ profile: null, error }),
    );
    return () => {
      live = false;
    };
  }, [key]);
  return state;
}

/**
 * The session's info: from the shared `sessions` list (the socket pushes it when the server
 * publishes a change, e.g. after a store) and from GET /sessions/{sid} on `refresh()` (after
 * a write, whose dirty entry the server may not push).
 */
export function useSessionInfo(sid: string): { info: SessionInfo | null; error: unknown; refresh: () => Promise<void> } {
  const list = useObservable(sessions);
  const fromList = list?.find((s) => s.id === sid) ?? null;
  const [fetched, setFetched] = useState<SessionInfo | null>(null);
  const [error, setError] = useState<unknown>(null);
  const [preferFetched, setPreferFetched] = useState(false);

  const refresh = useCallback(async () => {
    try {
      const info = await api.session(sid);
      setFetched(info);
      setPreferFetched(true);
      setError(null);
    } catch (e) {
      setError(e);
    }
  }, [sid]);

  useEffect(() => {
    void refresh();
  }, [refresh]);

  // A newer list entry (pushed by the server) wins over an older fetch.
  useEffect(() => {
    setPreferFetched(false);
  }, [fromList]);

  const info = preferFetched ? (fetched ?? fromList) : (fromList ?? fetched);
  return { info, error, refresh };
}
