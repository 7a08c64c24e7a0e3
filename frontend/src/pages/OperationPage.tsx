/**
 * Operation: control ownership, servo on/off, jog, moves, velocity, torque, cyclic set-points
 * and homing, with HALT and QUICK STOP always on screen, the limits that apply next to the
 * inputs, live position/velocity, and a compact 3D view (docs/api.md issue 4).
 *
 * Motion needs this tab to hold control (its token, taken in the header's control indicator)
 * and its WebSocket to be bound to that control: while motion started here runs, the page
 * sends a heartbeat every 50 ms and the server stops the axis when they stop (the dead-man).
 * When that happens the page shows why. Closing the tab stops the axis and disables the drive.
 */
import { useEffect, useState } from 'react';
import { api, operationApi } from '../api/client';
import type { Limits, ProfileSummary } from '../api/types';
import { CyclicPanel } from '../components/operation/CyclicPanel';
import { ControlCard } from '../components/operation/ControlCard';
import { useWriteGate } from '../components/ControlNote';
import { HomingPanel } from '../components/operation/HomingPanel';
import { useEntryUnit } from '../components/ValueEditor';
import { JogPanel } from '../components/operation/JogPanel';
import { MovePanel } from '../components/operation/MovePanel';
import { StopBar } from '../components/operation/StopBar';
import { TorquePanel } from '../components/operation/TorquePanel';
import { VelocityPanel } from '../components/operation/VelocityPanel';
import { ViewerFrame } from '../components/operation/ViewerFrame';
import type { PanelContext } from '../components/operation/context';
import { clearDeadman, heartbeatRunning, loadControl, me, operationLive, setMotion, startOperationStore, stopHeartbeat } from '../components/operation/operationStore';
import '../components/operation/operation.css';
import { FailureBox } from '../components/FailureBox';
import { LivePlot } from '../components/LivePlot';
import { type Failure, failureOf } from '../lib/codes';
import { formatEngineering } from '../lib/format';
import { formatQuantity } from '../lib/motionLimits';
import { notifyError } from '../state/notify';
import { useObservable } from '../state/observable';
import { applyState, liveSession, sessions, socket, socketStatus } from '../state/store';
import type { PageProps } from './registry';

type PanelId = 'jog' | 'move' | 'velocity' | 'torque' | 'cyclic' | 'homing';

const PANELS: ReadonlyArray<{ id: PanelId; title: string; modes: number[] }> = [
  { id: 'jog', title: 'Jog', modes: [3] },
  { id: 'move', title: 'Move (pp)', modes: [1] },
  { id: 'velocity', title: 'Velocity (pv)', modes: [3] },
  { id: 'torque', title: 'Torque (tq)', modes: [4] },
  { id: 'cyclic', title: 'Cyclic (csp/csv/cst)', modes: [8, 9, 10] },
  { id: 'homing', title: 'Homing (hm)', modes: [6] },
];

const VIEWER_KEY = 'servodesk.operation.viewer';

function readViewerChoice(): boolean {
  try {
    return localStorage.getItem(VIEWER_KEY) === '1';
  } catch {
    return false;
  }
}

function LimitsCard({ limits, failure, onReload }: { limits: Limits | null; failure: Failure | null; onReload: () => void }) {
  const u = limits?.units ?? {};
  const rows: Array<[string, string, string | undefined]> = limits
    ? [
        ['Position min', formatQuantity(limits.position_min, u.position), limits.sources.position_min],
        ['Position max', formatQuantity(limits.position_max, u.position), limits.sources.position_max],
        ['Max velocity', formatQuantity(limits.max_velocity, u.velocity), limits.sources.max_velocity],
        ['Max acceleration', formatQuantity(limits.max_acceleration, u.acceleration), limits.sources.max_acceleration],
        ['Max deceleration', formatQuantity(limits.max_deceleration, u.acceleration), limits.sources.max_deceleration],
        ['Max torque', formatQuantity(limits.max_torque, u.torque), limits.sources.max_torque],
      ]
    : [];
  return (
    <section className="card" data-testid="limits-card">
      <h2>
        Limits that apply
        <span className="h2-side">
          <button type="button" className="small-btn" onClick={onReload} data-testid="limits-reload">
            Read again
          </button>
        </span>
      </h2>
      {failure && (
        <>
          <FailureBox f={failure} testid="limits-error" />
          <div className="muted small">Inputs are checked by the server only until the limits can be read.</div>
        </>
      )}
      {limits && (
        <table className="grid" data-testid="limits-table">
          <tbody>
            {rows.map(([name, value, src]) => (
              <tr key={name}>
                <th className="muted">{name}</th>
                <td className="mono">{value === '—' ? <span className="muted">no limit</span> : value}</td>
                <td className="muted small mono">{src ?? ''}</td>
              </tr>
            ))}
            <tr>
              <th className="muted">Modes</th>
              <td colSpan={2} className="small">
                {limits.modes.map((m) => limits.mode_names[String(m)] ?? `mode ${m}`).join(', ')}
              </td>
            </tr>
          </tbody>
        </table>
      )}
      {!limits && !failure && <div className="muted">Reading the limits…</div>}
    </section>
  );
}

export function OperationPage({ sid }: PageProps) {
  const list = useObservable(sessions);
  const session = list?.find((s) => s.id === sid) ?? null;
  const source = liveSession(sid);
  const live = useObservable(source);
  const ws = useObservable(socketStatus);
  const op = useObservable(operationLive(sid));
  const gate = useWriteGate(sid);
  const state = live.state;
  const [limits, setLimits] = useState<Limits | null>(null);
  const [limitsFailure, setLimitsFailure] = useState<Failure | null>(null);
  const [limitsSettled, setLimitsSettled] = useState(false);
  const [profile, setProfile] = useState<ProfileSummary | null>(null);
  // Engineering units by default and the browser's choice after, the one the object editors
  // use (lib/units.ts, localStorage servodesk.entryUnit): a person who reads rpm and mm types
  // them on every page.
  const [entry, setEntry] = useEntryUnit();
  const [panel, setPanel] = useState<PanelId>('jog');
  const [showViewer, setShowViewer] = useState(() => readViewerChoice());

  function toggleViewer(on: boolean) {
    setShowViewer(on);
    try {
      localStorage.setItem(VIEWER_KEY, on ? '1' : '0');
    } catch {
      // Storage off: the choice lasts for this page view.
    }
  }

  function loadLimits() {
    operationApi.limits(sid).then(
      (l) => {
        setLimits(l);
        setLimitsFailure(null);
        setLimitsSettled(true);
      },
      (e: unknown) => {
        setLimitsFailure(failureOf(e, 'Read the limits'));
        setLimitsSettled(true);
      },
    );
  }

  useEffect(() => {
    startOperationStore();
    const unsub = socket.subscribe(sid);
    let alive = true;
    api.state(sid).then(
      (s) => alive && applyState(sid, s),
      (e: unknown) => alive && notifyError(e),
    );
    loadControl(sid);
    operationApi.motion(sid).then(
      (m) => alive && setMotion(sid, m),
      () => undefined,
    );
    loadLimits();
    return () => {
      alive = false;
      unsub();
      // Motion started here does not outlive the page: leaving it halts the axis.
      if (heartbeatRunning(sid)) {
        stopHeartbeat(sid);
        operationApi.halt(sid).catch(notifyError);
      }
    };
    // loadLimits only uses sid.
  }, [sid]);

  // The profile's modes, for when GET /limits failed (the panels still know what exists).
  const profileId = session?.profile_id ?? null;
  useEffect(() => {
    if (!profileId) return;
    let alive = true;
    api.profiles().then(
      (ps) => alive && setProfile(ps.find((p) => p.id === profileId) ?? null),
      () => undefined,
    );
    return () => {
      alive = false;
    };
  }, [profileId]);

  // Without the socket, poll the state once a second rather than show frozen values.
  useEffect(() => {
    if (ws.status === 'open') return;
    const t = setInterval(() => {
      api.state(sid).then(
        (s) => applyState(sid, s),
        () => undefined,
      );
    }, 1000);
    return () => clearInterval(t);
  }, [sid, ws.status]);

  if (list !== null && !session) {
    return (
      <div className="empty" data-testid="no-session">
        Session <span className="mono">{sid}</span> is not open. <a href="#/connect">Open it on the Connect page.</a>
      </div>
    );
  }

  const socketOpen = ws.status === 'open';
  // Holding control means holding its token (state/control), not only having the holder's
  // label; motion also needs this tab's WebSocket bound as the dead-man.
  const you = gate.view.you && gate.view.bind.state === 'bound';
  const modes = limits?.modes ?? profile?.modes ?? [];
  const ctx: PanelContext = { sid, limits, entry, state, you, socketOpen };
  const dm = op.deadman;

  return (
    <div className="stack" data-testid="operation-page">
      <StopBar sid={sid} state={state} motion={op.motion} heartbeat={op.heartbeat} />

      {dm && (
        <div className="deadman-banner" role="alert" data-testid="deadman-banner">
          <div>
            <strong>The dead-man stopped the motion.</strong> <span data-testid="deadman-reason">{dm.reason}</span>
            {dm.latency_ms !== null && (
              <span className="muted">
                {' '}
                · halt sent {dm.latency_ms} ms after the last heartbeat
                {dm.quick_stop_ms != null ? `, quick stop after ${dm.quick_stop_ms} ms` : ''}
              </span>
            )}
            {dm.message && <div>{dm.message}</div>}
            <div className="small">
              {dm.client === me() ? 'It was motion started from this tab. ' : dm.client ? `It was motion of client ${dm.client}. ` : ''}
              The drive was quick-stopped: check the axis, then servo on again before the next motion.
            </div>
          </div>
          <button type="button" className="small-btn" onClick={() => clearDeadman(sid)} data-testid="deadman-dismiss">
            Dismiss
          </button>
        </div>
      )}

      {!socketOpen && (
        <div className="socket-banner" role="alert" data-testid="socket-banner">
          <strong>No live connection to the server ({ws.status}).</strong> Motion needs this tab's WebSocket for its dead-man
          heartbeat, so the server refuses to start motion until it is back.{' '}
          {ws.detail ? <span className="muted">{ws.detail}</span> : null}
          {ws.retryIn !== null ? <span className="muted"> · retrying in {ws.retryIn} s</span> : null}
        </div>
      )}

      {state?.state === 'Fault' && (
        <div className="socket-banner" role="alert" data-testid="op-fault-banner">
          <strong>The drive is in Fault</strong>
          {state.error ? (
            <>
              : <span className="mono">{state.error.code_hex}</span> {state.error.name}.
            </>
          ) : (
            '.'
          )}{' '}
          <a href={`#/alarms/${encodeURIComponent(sid)}`}>See the cause and reset it on the Alarms page.</a>
        </div>
      )}

      <div className="op-grid">
        <div className="stack">
          <ControlCard sid={sid} state={state} socketOpen={socketOpen} />
          <section className="card" data-testid="motion-card">
            <h2>
              Motion
              <span className="h2-side">
                <span className="muted">Enter values in </span>
                <span className="segmented" role="group" aria-label="Entry units">
                  <button type="button" className={entry === 'raw' ? 'on' : ''} aria-pressed={entry === 'raw'} onClick={() => setEntry('raw')} data-testid="units-raw">
                    drive units
                  </button>
                  <button type="button" className={entry === 'eng' ? 'on' : ''} aria-pressed={entry === 'eng'} onClick={() => setEntry('eng')} data-testid="units-eng">
                    engineering
                  </button>
                </span>
              </span>
            </h2>
            <div className="op-tabs" role="tablist">
              {PANELS.map((p) => {
                const has = p.modes.some((m) => modes.includes(m));
                return (
                  <button
                    key={p.id}
                    type="button"
                    role="tab"
                    aria-selected={panel === p.id}
                    className={`op-tab${panel === p.id ? ' on' : ''}${has ? '' : ' unavailable'}`}
                    data-testid={`tab-${p.id}`}
                    title={has ? undefined : 'not available on this drive family (click for why)'}
                    onClick={() => setPanel(p.id)}
                  >
                    {p.title}
                  </button>
                );
              })}
            </div>
            {!you && (
              <div className="op-note" data-testid="no-control-note">
                {gate.view.owner && !gate.view.you
                  ? `Client ${gate.view.owner} holds control: motion from this tab is refused until they release it (or you force-take it at the top right).`
                  : gate.view.you
                    ? `Motion is disabled: ${gate.energise ?? "this tab's dead-man link is not bound"}.`
                    : 'Take control first (Take control, top right): motion is only accepted from the tab that holds control.'}
              </div>
            )}
            {you && state && state.state !== 'Operation enabled' && (
              <div className="op-note">The servo is off ({state.state}): press Servo on before starting motion.</div>
            )}
            {!limitsSettled ? (
              <div className="muted">Reading the limits…</div>
            ) : (
              <div key={`${panel}-${limits ? 'l' : 'n'}`}>
                {panel === 'jog' && <JogPanel ctx={ctx} modes={modes} />}
                {panel === 'move' && <MovePanel ctx={ctx} modes={modes} />}
                {panel === 'velocity' && <VelocityPanel ctx={ctx} modes={modes} />}
                {panel === 'torque' && <TorquePanel ctx={ctx} modes={modes} />}
                {panel === 'cyclic' && <CyclicPanel ctx={ctx} modes={modes} />}
                {panel === 'homing' && <HomingPanel ctx={ctx} modes={modes} />}
              </div>
            )}
          </section>
        </div>
        <div className="stack">
          <section className="card" data-testid="op-live">
            <h2>
              Live values <span className="h2-side mono muted">6064h · 606Ch</span>
            </h2>
            <table className="grid live-values">
              <thead>
                <tr>
                  <th />
                  <th className="num">Drive units</th>
                  <th className="num">Engineering</th>
                </tr>
              </thead>
              <tbody>
                <tr>
                  <th>Position</th>
                  <td className="mono num big" data-testid="live-position-raw">
                    {state?.position ?? '—'} <span className="unit">{state?.position_raw_unit ?? ''}</span>
                  </td>
                  <td className="mono num big">{formatEngineering(state?.position_eng, state?.position_unit)}</td>
                </tr>
                <tr>
                  <th>Velocity</th>
                  <td className="mono num big" data-testid="live-velocity-raw">
                    {state?.velocity ?? '—'} <span className="unit">{state?.velocity_raw_unit ?? ''}</span>
                  </td>
                  <td className="mono num big">{formatEngineering(state?.velocity_eng, state?.velocity_unit)}</td>
                </tr>
              </tbody>
            </table>
            <LivePlot source={source} positionUnit={state?.position_unit ?? 'raw'} velocityUnit={state?.velocity_unit ?? 'raw'} />
          </section>
          <LimitsCard limits={limits} failure={limitsFailure} onReload={loadLimits} />
          <section className="card" data-testid="op-viewer">
            <h2>
              3D view <span className="h2-side"><a href={`#/view3d/${encodeURIComponent(sid)}`}>open large</a></span>
            </h2>
            {showViewer ? (
              <>
                <ViewerFrame compact sid={sid} />
                <button type="button" className="small-btn" onClick={() => toggleViewer(false)} data-testid="op-viewer-hide">
                  Hide the 3D view
                </button>
              </>
            ) : (
              <div className="viewer-off">
                <button type="button" onClick={() => toggleViewer(true)} data-testid="op-viewer-show">
                  Show the 3D view here
                </button>
                <div className="muted small">
                  Off by default: the 3D view renders in this tab, and on a machine without graphics acceleration it can delay
                  the page's dead-man heartbeats enough for the server to stop a jog.
                </div>
              </div>
            )}
          </section>
        </div>
      </div>
    </div>
  );
}
