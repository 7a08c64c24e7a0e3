/**
 * Users (docs/security.md "Users", "Sessions"): the accounts and everyone's login sessions
 * (administrators: the manage_users right), and the caller's own API tokens for scripts.
 * Ending a session closes its WebSockets at once: the drives it was the dead-man of stop.
 */
import { type FormEvent, useCallback, useEffect, useState } from 'react';
import { hasRight, me } from '../api/auth';
import { type Account, type ApiTokenCreated, type ApiTokenInfo, type LoginSession, ROLES, usersApi } from '../api/users';
import '../components/auth/auth.css';
import { notify, notifyError } from '../state/notify';
import { useObservable } from '../state/observable';
import type { PageProps } from './registry';

function when(t: number | null): string {
  return t === null ? '—' : new Date(t * 1000).toLocaleString();
}

function Accounts() {
  const [rows, setRows] = useState<Account[]>([]);
  const [name, setName] = useState('');
  const [role, setRole] = useState<string>('operator');
  const [password, setPassword] = useState('');
  const load = useCallback(() => {
    usersApi.list().then(setRows, notifyError);
  }, []);
  useEffect(load, [load]);

  async function add(e: FormEvent) {
    e.preventDefault();
    try {
      await usersApi.create(name, role, password);
      notify({ kind: 'info', title: `Account ${name} added (${role})`, message: '', detail: null, hint: null });
      setName('');
      setPassword('');
      load();
    } catch (err) {
      notifyError(err);
    }
  }

  async function act(fn: () => Promise<unknown>) {
    try {
      await fn();
    } catch (err) {
      notifyError(err);
    }
    load();
  }

  return (
    <section className="card" data-testid="users-accounts">
      <h2>Accounts</h2>
      <table>
        <thead>
          <tr>
            <th>Name</th>
            <th>Role</th>
            <th>State</th>
            <th>Created</th>
            <th />
          </tr>
        </thead>
        <tbody>
          {rows.map((u) => (
            <tr key={u.name} data-testid={`account-${u.name}`}>
              <td>{u.name}</td>
              <td>
                <select value={u.role} onChange={(e) => void act(() => usersApi.update(u.name, { role: e.target.value }))}>
                  {ROLES.map((r) => (
                    <option key={r}>{r}</option>
                  ))}
                </select>
              </td>
              <td>{u.disabled ? 'disabled' : 'enabled'}</td>
              <td>{when(u.created)}</td>
              <td>
                <button type="button" className="small-btn" onClick={() => void act(() => usersApi.update(u.name, { disabled: !u.disabled }))}>
                  {u.disabled ? 'Enable' : 'Disable'}
                </button>{' '}
                <button type="button" className="small-btn" onClick={() => void act(() => usersApi.remove(u.name))}>
                  Remove
                </button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      <form className="form-grid" onSubmit={(e) => void add(e)}>
        <input placeholder="name" data-testid="new-user-name" value={name} onChange={(e) => setName(e.target.value)} required />
        <select data-testid="new-user-role" value={role} onChange={(e) => setRole(e.target.value)}>
          {ROLES.map((r) => (
            <option key={r}>{r}</option>
          ))}
        </select>
        <input
          placeholder="password (8 or more characters)"
          type="password"
          autoComplete="new-password"
          data-testid="new-user-password"
          value={password}
          onChange={(e) => setPassword(e.target.value)}
          required
        />
        <button type="submit" data-testid="new-user-add">
          Add account
        </button>
      </form>
      {useObservable(me)?.mode === 'single-user' && (
        <p className="muted small">Once an account exists, this loopback server asks everyone to log in (servodesk serve --single-user keeps it login-free).</p>
      )}
    </section>
  );
}

function Sessions() {
  const [rows, setRows] = useState<LoginSession[]>([]);
  const load = useCallback(() => {
    usersApi.sessions().then(setRows, notifyError);
  }, []);
  useEffect(() => {
    load();
    const t = window.setInterval(load, 5000);
    return () => window.clearInterval(t);
  }, [load]);
  const mine = useObservable(me)?.session ?? null;

  async function end(s: LoginSession) {
    try {
      await usersApi.endSession(s.id);
      notify({ kind: 'info', title: `Session of ${s.user} ended`, message: 'its WebSockets closed: motion it held stopped', detail: null, hint: null });
    } catch (err) {
      notifyError(err);
    }
    load();
  }

  return (
    <section className="card" data-testid="users-sessions">
      <h2>Login sessions</h2>
      {rows.length === 0 ? (
        <p className="muted">Nobody is logged in.</p>
      ) : (
        <table>
          <thead>
            <tr>
              <th>User</th>
              <th>From</th>
              <th>Logged in</th>
              <th>Last request</th>
              <th>WebSockets</th>
              <th />
            </tr>
          </thead>
          <tbody>
            {rows.map((s) => (
              <tr key={s.id} data-testid={`login-session-${s.user}`}>
                <td>
                  {s.user}
                  {s.id === mine ? ' (you)' : ''}
                </td>
                <td className="mono">{s.address}</td>
                <td>{when(s.created)}</td>
                <td>{when(s.last_seen)}</td>
                <td>{s.websockets}</td>
                <td>
                  <button type="button" className="small-btn" data-testid={`end-session-${s.user}`} onClick={() => void end(s)}>
                    End session
                  </button>
                </td>
              </tr>
            ))}
          </tbody>
        </table>
      )}
    </section>
  );
}

function Tokens() {
  const [rows, setRows] = useState<ApiTokenInfo[]>([]);
  const [label, setLabel] = useState('');
  const [made, setMade] = useState<ApiTokenCreated | null>(null);
  const load = useCallback(() => {
    usersApi.tokens().then(setRows, notifyError);
  }, []);
  useEffect(load, [load]);

  async function create(e: FormEvent) {
    e.preventDefault();
    try {
      setMade(await usersApi.createToken(label));
      setLabel('');
    } catch (err) {
      notifyError(err);
    }
    load();
  }

  return (
    <section className="card" data-testid="users-tokens">
      <h2>Your API tokens</h2>
      <p className="muted small">For scripts: send one as Authorization: Bearer &lt;token&gt;, never in a URL.</p>
      {made && (
        <p data-testid="token-secret">
          New token (shown this once): <code className="secret">{made.secret}</code>
        </p>
      )}
      <table>
        <tbody>
          {rows.map((t) => (
            <tr key={t.id}>
              <td className="mono">{t.id}</td>
              <td>{t.label || '—'}</td>
              <td>made {when(t.created)}</td>
              <td>last used {when(t.last_used)}</td>
              <td>
                <button
                  type="button"
                  className="small-btn"
                  onClick={() =>
                    void usersApi.deleteToken(t.id).then(load, (err: unknown) => {
                      notifyError(err);
                    })
                  }
                >
                  Delete
                </button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      <form onSubmit={(e) => void create(e)}>
        <input placeholder="what it is for" value={label} maxLength={100} onChange={(e) => setLabel(e.target.value)} />{' '}
        <button type="submit">Make a token</button>
      </form>
    </section>
  );
}

export function UsersPage(_: PageProps) {
  const m = useObservable(me);
  const admin = hasRight('manage_users');
  return (
    <div className="users-page stack" data-testid="users-page">
      {admin ? (
        <>
          <Accounts />
          {m?.mode === 'login' && <Sessions />}
        </>
      ) : (
        <p className="muted">Accounts and sessions are managed by an administrator (your role: {m?.role}).</p>
      )}
      {m?.mode === 'login' && <Tokens />}
    </div>
  );
}
