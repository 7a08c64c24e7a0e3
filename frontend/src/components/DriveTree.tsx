/**
 * The drive tree at the top of the sidebar (issue 48, "many axes at a glance"): every open
 * session grouped by bus, then drive, then axis (lib/driveTree), each axis with its CiA 402
 * state, an alarm badge when it has one, and who holds control. A row is a link to the same
 * page for that drive (as the header's drive select does); a bus folds.
 *
 * Live from the store, nothing polled: the state from the session list (the server sends
 * `sessions` on every change of a drive's state, and the store keeps it in step with the
 * `state` messages), the alarm code from the live state of the drives a page subscribed to
 * (lib/driveTree treeAlarm says why only those), who holds control from state/control (one
 * GET .../control per drive, then the `control` messages every socket gets). The tree does not
 * subscribe to the drives itself: a subscription raises the server's reads of a drive from
 * 1 Hz to the live rate (services/session.py `_poll`), a cost a sidebar must not put on every
 * bus all the time.
 */
import { useEffect, useReducer, useState, useSyncExternalStore, type KeyboardEvent } from 'react';
import { me } from '../api/auth';
import { findPage } from '../pages/registry';
import { treeAlarm, treeControl, driveTree, type TreeAlarm, type TreeAxis, type TreeBus, type TreeDrive } from '../lib/driveTree';
import { useControl } from '../state/control';
import { useObservable } from '../state/observable';
import { currentSession, navigate, routeHref } from '../state/router';
import { liveSession, sessions } from '../state/store';
import { StatePill } from './StatePill';
import './driveTree.css';

/** A subscribed drive's state arrives at least once a second (services/session.py `_poll`);
 * one older than this is from a page that closed and may no longer hold. */
const FRESH_MS = 3000;

/** The row's alarm, re-rendered only when it changes (not with every 20 Hz state). */
function useAlarm(sid: string, sessionState: string): TreeAlarm | null {
  const obs = liveSession(sid);
  const [tick, bump] = useReducer((n: number) => n + 1, 0);
  const key = useSyncExternalStore(obs.subscribe, () => {
    const l = obs.get();
    const fresh = l.received !== null && Date.now() - l.received < FRESH_MS;
    const a = treeAlarm(sessionState, l.state, fresh);
    // A string: the same alarm is the same snapshot, so the row does not re-render.
    return a ? JSON.stringify(a) : '';
  });
  const alarm = key ? (JSON.parse(key) as TreeAlarm) : null;
  const fromLive = alarm?.live ?? false;
  // A code read from the live state ages out when its page closes: look again then (a local
  // timer while such a code is shown, nothing sent).
  useEffect(() => {
    if (!fromLive) return undefined;
    const t = window.setTimeout(bump, FRESH_MS);
    return () => window.clearTimeout(t);
  }, [fromLive, key, tick]);
  return alarm;
}

function onSpace(e: KeyboardEvent<HTMLAnchorElement>, page: string, sid: string) {
  // A link follows Enter by itself; Space, as on a button, too.
  if (e.key === ' ') {
    e.preventDefault();
    navigate(page, sid);
  }
}

function AxisLink({ axis, name, page, selected, myUser }: { axis: TreeAxis; name: string; page: string; selected: boolean; myUser: string | null }) {
  const s = axis.session;
  const alarm = useAlarm(s.id, s.state);
  const control = treeControl(useControl(s.id), myUser);
  const spoken = [`${name}, ${axis.label}: ${s.state}`, alarm ? `alarm ${alarm.title}` : null, s.connected ? null : 'link lost', `control ${control.text}`];
  return (
    <a
      href={routeHref(page, s.id)}
      className={`tree-row${selected ? ' selected' : ''}`}
      aria-current={selected ? 'true' : undefined}
      aria-label={spoken.filter(Boolean).join(', ')}
      title={`${s.id}: ${name}, ${axis.label}${s.simulated ? ' (simulated)' : ''}`}
      data-testid={`tree-drive-${s.id}`}
      data-state={s.state}
      data-alarm={alarm?.text ?? ''}
      data-control={control.who}
      onKeyDown={(e) => onSpace(e, page, s.id)}
    >
      <span className="tree-line">
        <span className="tree-name" data-testid="tree-drive-name">
          {name}
        </span>
        <span className="tree-node mono">{axis.label}</span>
      </span>
      <span className="tree-line tree-status">
        <StatePill state={s.state} testid="tree-drive-state" />
        {alarm && (
          <span className={`tree-alarm tree-alarm-${alarm.kind}`} data-testid="tree-drive-alarm" title={alarm.title}>
            {alarm.text}
          </span>
        )}
        {!s.connected && (
          <span className="tree-alarm tree-alarm-warning" title="the drive does not answer the session's polls">
            no link
          </span>
        )}
        <span className={`tree-ctl tree-ctl-${control.who}`} title={control.title}>
          <span className="tree-ctl-label">Control</span>{' '}
          <span className="tree-ctl-holder" data-testid="tree-drive-control">
            {control.text}
          </span>
        </span>
      </span>
    </a>
  );
}

function DriveItem({ drive, page, selected, myUser }: { drive: TreeDrive; page: string; selected: string | null; myUser: string | null }) {
  if (drive.axes.length === 1) {
    const axis = drive.axes[0] as TreeAxis;
    return (
      <li>
        <AxisLink axis={axis} name={drive.name} page={page} selected={axis.session.id === selected} myUser={myUser} />
      </li>
    );
  }
  // A unit of several axes (an SLMP station, a PROFINET device): the drive names them, each
  // axis is a row of its own.
  return (
    <li className="tree-unit">
      <div className="tree-unit-head">
        <span className="tree-name">{drive.name}</span>
        <span className="tree-node mono">{drive.label}</span>
      </div>
      <ul className="tree-axes">
        {drive.axes.map((a) => (
          <li key={a.session.id}>
            <AxisLink axis={a} name={drive.name} page={page} selected={a.session.id === selected} myUser={myUser} />
          </li>
        ))}
      </ul>
    </li>
  );
}

function BusGroup({ bus, page, selected, myUser }: { bus: TreeBus; page: string; selected: string | null; myUser: string | null }) {
  const [folded, setFolded] = useState(false);
  const listId = `tree-bus-${bus.key.replace(/[^A-Za-z0-9_-]/g, '_')}`;
  const count = bus.drives.reduce((n, d) => n + d.axes.length, 0);
  const faults = bus.faults;
  return (
    <div className="tree-bus" data-testid="tree-bus" data-bus={bus.key}>
      <button
        type="button"
        className="tree-bus-head"
        aria-expanded={!folded}
        aria-controls={listId}
        title={`${bus.label}: ${count} ${count === 1 ? 'axis' : 'axes'} open${folded ? ' (click to show)' : ''}`}
        onClick={() => setFolded((f) => !f)}
        data-testid="tree-bus-head"
      >
        <span className="tree-caret" aria-hidden="true">
          {folded ? '▸' : '▾'}
        </span>
        <span className="tree-bus-label" data-testid="tree-bus-label">
          {bus.label}
        </span>
        {folded && <span className="tree-bus-count">{count}</span>}
        {folded && faults > 0 && (
          <span className="tree-alarm tree-alarm-fault" title={`${faults} in Fault`}>
            {faults} FAULT
          </span>
        )}
      </button>
      <ul id={listId} className="tree-drives" hidden={folded}>
        {bus.drives.map((d) => (
          <DriveItem key={d.key} drive={d} page={page} selected={selected} myUser={myUser} />
        ))}
      </ul>
    </div>
  );
}

export function DriveTree({ active }: { active: string }) {
  const list = useObservable(sessions);
  const selected = useObservable(currentSession);
  const who = useObservable(me);
  const page = findPage(active);
  // The same page for another drive, as the header's select does; Overview from a global page.
  const target = page?.scope === 'session' ? page.id : 'overview';
  return (
    <nav className="tree" aria-label="Drives" data-testid="drive-tree">
      <div className="nav-group-title">Drives</div>
      {list === null ? (
        <div className="tree-empty muted">Loading…</div>
      ) : list.length === 0 ? (
        <div className="tree-empty muted" data-testid="tree-empty">
          No drive open. <a href={routeHref('connect')}>Connect</a>
        </div>
      ) : (
        driveTree(list).map((b) => <BusGroup key={b.key} bus={b} page={target} selected={selected} myUser={who?.user ?? null} />)
      )}
    </nav>
  );
}
