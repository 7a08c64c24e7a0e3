/**
 * Entry point: ask the server who is logged in (GET /auth/me); on 401 show the login page,
 * otherwise start the shared socket and render the shell.
 */
import { StrictMode } from 'react';
import { createRoot } from 'react-dom/client';
import 'uplot/dist/uPlot.min.css';
import './styles.css';
import { captureTokenFromUrl, endSession, me, refreshMe } from './api/auth';
import { App } from './App';
import { LoginPage } from './components/auth/LoginPage';
import { loadCjkFont } from './lib/cjkFont';
import { startIdleLock } from './lib/idleLock';
import { startTheme } from './lib/theme';
import { useObservable } from './state/observable';
import { startControlStore } from './state/control';
import { startStore } from './state/store';

captureTokenFromUrl();
// Before anything renders, the login page included: no white flash in a dark cabinet.
startTheme();

/** The login page while nobody is logged in (a login reloads the page), else the app. */
function Root() {
  const who = useObservable(me);
  if (who === undefined) return null;
  return who === null ? <LoginPage /> : <App />;
}

const root = document.getElementById('root');
if (!root) throw new Error('index.html has no #root element');
// The CJK subset before anything is drawn (lib/cjkFont.ts: on demand it drew boxes).
void Promise.all([refreshMe(), loadCjkFont()]).then(([who]) => {
  if (who !== null) {
    startStore();
    startControlStore();
    startIdleLock(who, endSession);
  }
  createRoot(root).render(
    <StrictMode>
      <Root />
    </StrictMode>,
  );
});
