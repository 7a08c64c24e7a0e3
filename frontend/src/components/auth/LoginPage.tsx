/**
 * The login page (docs/security.md "Users"), shown instead of the app when GET /auth/me
 * answers 401. A successful login reloads the page with the session cookie set; a lock-out
 * says until when.
 */
import { type FormEvent, useState } from 'react';
import { login, loginReason } from '../../api/auth';
import { useObservable } from '../../state/observable';
import './auth.css';

export function LoginPage() {
  const [user, setUser] = useState('');
  const [password, setPassword] = useState('');
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<string | null>(null);
  const reason = useObservable(loginReason);

  async function submit(e: FormEvent) {
    e.preventDefault();
    setBusy(true);
    setError(null);
    const failed = await login(user, password);
    if (failed === null) {
      window.location.reload();
      return;
    }
    setBusy(false);
    setPassword('');
    const until = failed.until ? ` (until ${new Date(failed.until * 1000).toLocaleTimeString()})` : '';
    setError(`${failed.message}${until}${failed.hint ? `. ${failed.hint}` : ''}`);
  }

  return (
    <div className="login-shell" data-testid="login-page">
      <form className="card login-card" onSubmit={(e) => void submit(e)}>
        <div className="brand">
          <span className="brand-mark" aria-hidden="true">
            ▮
          </span>
          servodesk
        </div>
        <h1>Log in</h1>
        {reason && (
          <p className="muted" data-testid="login-reason">
            {reason}
          </p>
        )}
        <label>
          User
          <input data-testid="login-user" autoComplete="username" value={user} onChange={(e) => setUser(e.target.value)} required autoFocus />
        </label>
        <label>
          Password
          <input
            data-testid="login-password"
            type="password"
            autoComplete="current-password"
            value={password}
            onChange={(e) => setPassword(e.target.value)}
            required
          />
        </label>
        {error && (
          <p className="inline-error" role="alert" data-testid="login-error">
            {error}
          </p>
        )}
        <button type="submit" data-testid="login-submit" disabled={busy || !user || !password}>
          {busy ? 'Logging in…' : 'Log in'}
        </button>
        <p className="muted small">Accounts are made by an administrator (Users page, or servodesk users add on the server).</p>
      </form>
    </div>
  );
}
