/**
 * The app shell, laid out like the LEC-S-NP PROFINET card's web server (LECSN manual §20.7):
 * a header with the drive's name and state, a left navigation of pages, and the page; the bus
 * status bar at the foot (issue 48).
 */
import { useEffect } from 'react';
import { Header } from './components/Header';
import { Nav } from './components/Nav';
import { Notices } from './components/Notices';
import { StatusBar } from './components/StatusBar';
import { findPage } from './pages/registry';
import { useObservable } from './state/observable';
import { currentSession, navigate, parseHash, routeHref, useRoute } from './state/router';
import { sessions } from './state/store';

export function App() {
  const route = useRoute();
  const list = useObservable(sessions);
  const current = useObservable(currentSession);
  const page = findPage(route.page);

  // A session-scoped page without a session in the URL shows the last drive looked at, or the
  // first open one.
  const fallbackSid = current ?? list?.[0]?.id ?? null;
  const sid = page?.scope === 'session' ? (route.sid ?? fallbackSid) : null;

  useEffect(() => {
    // The address as it is now, not as it was at render: a link followed between the render
    // and this effect (a bookmark opened right after logging in) must not be sent to Connect.
    if (!page && !findPage(parseHash(window.location.hash).page)) navigate('connect');
  }, [page]);

  useEffect(() => {
    if (page?.scope === 'session' && sid && route.sid !== sid) {
      window.history.replaceState(null, '', routeHref(page.id, sid));
    }
    if (sid) currentSession.set(sid);
  }, [page, sid, route.sid]);

  const Page = page?.component;
  return (
    <div className="shell">
      <Header sid={sid ?? current} />
      <div className="shell-body">
        <Nav active={page?.id ?? ''} sid={sid ?? fallbackSid} />
        <main className="page" data-testid={`page-${page?.id ?? 'none'}`}>
          {page && (
            <div className="page-head">
              <h1>{page.title}</h1>
              <span className="page-sub">{page.description}</span>
            </div>
          )}
          {Page && page?.scope === 'global' && <Page sid="" />}
          {Page && page?.scope === 'session' && sid && <Page key={sid} sid={sid} />}
          {page?.scope === 'session' && !sid && (
            <div className="empty" data-testid="no-session">
              No drive session is open. <a href={routeHref('connect')}>Open one on the Connect page.</a>
            </div>
          )}
        </main>
      </div>
      <StatusBar />
      <Notices />
    </div>
  );
}
