/**
 * The header: product name, the drive in view (name, node, profile, state, simulated badge),
 * on session pages who holds control of it (Take / Release / Force take), STOP ALL (every
 * page: components/GlobalStop.tsx), a drive switcher, and the WebSocket connection indicator.
 */
import type { SessionInfo } from '../api';
import { nodeLabel } from '../lib/network';
import { useObservable } from '../state/observable';
import { navigate, useRoute } from '../state/router';
import { liveSession, sessions, socketStatus } from '../state/store';
import { findPage } from '../pages/registry';
import { ControlIndicator } from './ControlIndicator';
import { GlobalStopButton } from './GlobalStop';
import { UserMenu } from './auth/UserMenu';
import { StatePill } from './StatePill';

function ConnectionIndicator() {
  const s = useObservable(socketStatus);
  const label =
    s.status === 'open'
      ? 'Live'
      : s.status === 'connecting'
        ? 'Connecting…'
        : s.status === 'incompatible'
          ? 'Incompatible server'
          : s.retryIn !== null
            ? `Offline · retry in ${s.retryIn}s`
            : 'Offline';
  const title =
    s.status === 'open'
      ? 'WebSocket connected: live values are streaming'
      : `WebSocket ${s.status}${s.detail ? `: ${s.detail}` : ''}`;
  return (
    <span className={`conn conn-${s.status}`} data-testid="ws-status" data-status={s.status} title={title}>
      <span className="conn-dot" aria-hidden="true" />
      {label}
    </span>
  );
}

function DriveTitle({ session }: { session: SessionInfo }) {
  const liveState = useObservable(liveSession(session.id)).state;
  const state = liveState?.state ?? session.state;
  const name = session.identity.device_name || session.profile_name;
  const meta = `${nodeLabel(session.interface, session.node_id)} · ${session.fieldbus} · ${session.interface}:${session.channel}`;
  return (
    <div className="drive-title">
      <span className="drive-name" data-testid="header-drive-name" title={name === session.profile_name ? name : `${name} (${session.profile_name})`}>
        {name}
      </span>
      <span className="drive-meta mono" title={meta}>
        {meta}
      </span>
      {session.simulated && (
        <span className="badge badge-sim" title={session.note ?? 'simulated twin'}>
          SIM
        </span>
      )}
      <StatePill state={state} testid="header-state" />
    </div>
  );
}

export function Header({ sid }: { sid: string | null }) {
  const list = useObservable(sessions) ?? [];
  const route = useRoute();
  const session = list.find((s) => s.id === sid) ?? null;
  const page = findPage(route.page);
  return (
    <header className="header">
      <div className="brand">
        <span className="brand-mark" aria-hidden="true">
          ▮
        </span>
        servodesk
        {/* Who is logged in (or the single-user mode) where the tagline was: the right side
            of the header needs its room for the drive's state on a laptop screen. */}
        <UserMenu />
      </div>
      <div className="header-drive">
        {session ? <DriveTitle session={session} /> : <span className="muted">no drive selected</span>}
      </div>
      <div className="header-right">
        {/* Always shown, on every page: stops every axis this user controls (issue 48). */}
        <GlobalStopButton />
        {session && page?.scope === 'session' && <ControlIndicator key={session.id} sid={session.id} />}
        {list.length > 0 && (
          <label className="session-switch">
            <span className="muted">Drive</span>
            <select
              data-testid="session-select"
              value={session?.id ?? ''}
              onChange={(e) => navigate(page?.scope === 'session' ? page.id : 'overview', e.target.value)}
            >
              {!session && <option value="">—</option>}
              {list.map((s) => (
                <option key={s.id} value={s.id}>
                  {s.id}
                </option>
              ))}
            </select>
          </label>
        )}
        <ConnectionIndicator />
      </div>
    </header>
  );
}
