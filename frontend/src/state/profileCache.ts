/**
 * Profiles with their full object list (GET /profiles/{id}), loaded once per profile and
 * shared by the Parameters and Object dictionary pages (lecsn-t's answer is ~1.3 MB), and the
 * open session's SessionInfo kept fresh for the dirty markers.
 */
import { useCallback, useEffect, useState } from 'react';
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

export interface ProfileLoad {
  profile: ProfileDetail | null;
  error: unknown;
}

export function useProfile(id: string | null): ProfileLoad {
  const [state, setState] = useState<ProfileLoad>({ profile: null, error: null });
  useEffect(() => {
    if (!id) return;
    let live = true;
    setState({ profile: null, error: null });
    loadProfile(id).then(
      (profile) => live && setState({ profile, error: null }),
      (error: unknown) => live && setState({ profile: null, error }),
    );
    return () => {
      live = false;
    };
  }, [id]);
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
