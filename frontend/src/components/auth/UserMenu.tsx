/**
 * The header's user menu: who is logged in, their role, Log out; or, on a loopback server
 * without accounts, that this is the single-user mode (no login, every right).
 */
import { logout, me } from '../../api/auth';
import { useObservable } from '../../state/observable';
import './auth.css';

export function UserMenu() {
  const m = useObservable(me);
  if (!m || m.user === '?') return null; // Not logged in, or the server did not answer.
  if (m.mode === 'single-user') {
    return (
      <span className="user-menu user-single" data-testid="user-menu" data-mode="single-user" title="Only this machine reaches the server; nobody logs in and every right is allowed. Adding an account turns logins on.">
        single-user mode<span className="user-single-more"> (loopback, no login)</span>
      </span>
    );
  }
  return (
    <span className="user-menu" data-testid="user-menu" data-mode="login" data-user={m.user} data-role={m.role}>
      <span className="user-name" data-testid="user-name">
        {m.user}
      </span>
      <span className="badge" data-testid="user-role">
        {m.role}
      </span>
      <button type="button" className="small-btn" data-testid="logout" onClick={() => void logout()}>
        Log out
      </button>
    </span>
  );
}
