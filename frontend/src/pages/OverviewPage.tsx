/**
 * Overview of one drive: identity (1018h), the CiA 402 state machine with the current state
 * lit, the decoded statusword, mode of operation, live actual position and velocity (raw and
 * engineering), a plot of the last seconds, state commands, and the current error in Fault.
 *
 * Live values come over the WebSocket; while it is down the page polls GET .../state once a
 * second so it never shows stale data as if it were live.
 */
import { type ReactElement, useEffect, useState } from 'react';
import type { DriveState, ErrorInfo, Identity, SessionInfo, StateCommand } from '../api';
import { api } from '../api/client';
import { ControlNote, useWriteGate } from '../components/ControlNote';
import { LivePlot } from '../components/LivePlot';
import { ReportCard } from '../components/ReportCard';
import { StateDiagram } from '../components/StateDiagram';
import { StatePill } from '../components/StatePill';
import { StatuswordTable } from '../components/StatuswordTable';
import { modeName } from '../lib/cia402';
import { formatEngineering, toHex } from '../lib/format';
import { networkState } from '../lib/nmt';
import { notify, notifyError } from '../state/notify';
import { useObservable } from '../state/observable';
import { applyState, liveSession, sessions, socket, socketStatus } from '../state/store';
import type { PageProps } from './registry';

interface CommandDef {
  command: StateCommand;
  label: string;
  /** CiA 402-2 table 29 transition numbers, for the tooltip. */
  transitions: string;
}

const SHORTCUTS: readonly CommandDef[] = [
  { command: 'enable', label: 'Enable', transitions: 'walk to Operation enabled (2, 3, 4 as needed)' },
  { command: 'disable', label: 'Disable', transitions: 'walk to Switch on disabled' },
];

const COMMANDS: readonly CommandDef[] = [
  { command: 'shutdown', label: 'Shutdown', transitions: 'transitions 2, 6, 8' },
  { command: 'switch_on', label: 'Switch on', transitions: 'transition 3' },
  { command: 'enable_operation', label: 'Enable operation', transitions: 'transitions 4, 16' },
  { command: 'disable_operation', label: 'Disable operation', transitions: 'transition 5' },
  { command: 'disable_voltage', label: 'Disable voltage', transitions: 'transitions 7, 9, 10, 12' },
  { command: 'fault_reset', label: 'Fault reset', transitions: 'transition 15 (rising edge of controlword bit 7)' },
];

/** Commands that power the motor (servo on): they need control and the bound dead-man link. */
const ENERGISING: ReadonlySet<StateCommand> = new Set<StateCommand>(['enable', 'switch_on', 'enable_operation', 'switch_on_enable']);

const QUICK_STOP: CommandDef = { command: 'quick_stop', label: 'Quick stop', transitions: 'transitions 7, 10, 11' };

function hexDec(v: number | null | undefined): ReactElement {
  if (v === null || v === undefined) return <span className="muted">—</span>;
  return (
    <>
      <span className="mono">{toHex(v, 'UNSIGNED32')}</span> <span className="mono muted">({v})</span>
    </>
  );
}

function IdentityCard({ session }: { session: SessionInfo }) {
  const id: Identity = session.identity;
  return (
    <section className="card" data-testid="identity">
      <h2>Identity</h2>
      <table className="kv">
        <tbody>
          <tr>
            <th>Device name</th>
            <td data-testid="identity-device-name">{id.device_name ?? '—'}</td>
          </tr>
          <tr>
            <th>Vendor id (1018h:01)</th>
            <td data-testid="identity-vendor-id">{hexDec(id.vendor_id)}</td>
          </tr>
          <tr>
            <th>Product code (1018h:02)</th>
            <td data-testid="identity-product-code">{hexDec(id.product_code)}</td>
          </tr>
          <tr>
            <th>Revision (1018h:03)</th>
            <td>{hexDec(id.revision)}</td>
          </tr>
          <tr>
            <th>Serial number (1018h:04)</th>
            <td>{hexDec(id.serial)}</td>
          </tr>
          <tr>
            <th>Hardware version</th>
            <td className="mono">{id.hardware_version ?? '—'}</td>
          </tr>
          <tr>
            <th>Software version</th>
            <td className="mono">{id.software_version ?? '—'}</td>
          </tr>
          <tr>
            <th>Profile</th>
            <td>
              {session.profile_name} <span className="mono muted">({session.profile_id})</span>
            </td>
          </tr>
          {session.encoder?.source === '608Fh' && (
            <tr>
              <th>Encoder</th>
              <td data-testid="identity-encoder">
                <span className="mono">{session.encoder.counts_per_rev}</span> counts/rev{' '}
                <span className="muted">
                  (608Fh)
                  {session.encoder.rescaled ? ' · not the profile’s encoder: deg and rpm are converted for this one' : ''}
                </span>
              </td>
            </tr>
          )}
          <tr>
            <th>Link</th>
            <td className="mono">
              {session.fieldbus} · node {session.node_id} · {session.interface}:{session.channel} ·{' '}
              <span title={networkState(session).title} data-testid="overview-network-state">
                {networkState(session).label} {networkState(session).value}
              </span>
            </td>
          </tr>
        </tbody>
      </table>
      {session.simulated && (
        <div className="sim-note" data-testid="sim-note">
          <span className="badge badge-sim">SIM</span> Simulated twin{session.note ? `: ${session.note}` : ''}
        </div>
      )}
    </section>
  );
}

function LiveValues({ state }: { state: DriveState }) {
  const rows = [
    {
      key: 'position',
      label: 'Actual position (6064h)',
      raw: state.position,
      rawUnit: state.position_raw_unit ?? null,
      eng: state.position_eng,
      unit: state.position_unit,
    },
    {
      key: 'velocity',
      label: 'Actual velocity (606Ch)',
      raw: state.velocity,
      rawUnit: state.velocity_raw_unit ?? null,
      eng: state.velocity_eng,
      unit: state.velocity_unit,
    },
  ];
  return (
    <table className="grid live-values" data-testid="live-values">
      <thead>
        <tr>
          <th />
          <th className="num">Raw (drive units)</th>
          <th className="num">Engineering</th>
        </tr>
      </thead>
      <tbody>
        {rows.map((r) => (
          <tr key={r.key}>
            <th>{r.label}</th>
            <td className="mono num big" data-testid={`${r.key}-raw`}>
              {r.raw ?? '—'} <span className="unit">{r.rawUnit ?? ''}</span>
            </td>
            <td className="mono num big" data-testid={`${r.key}-eng`}>
              {formatEngineering(r.eng, null)} <span className="unit">{r.unit ?? ''}</span>
            </td>
          </tr>
        ))}
      </tbody>
    </table>
  );
}

function FaultCard({ error, code }: { error: ErrorInfo | null; code: number | null }) {
  return (
    <section className="card card-fault" data-testid="fault">
      <h2>
        Current error
        {code !== null && <span className="h2-side mono">603Fh = {toHex(code, 'UNSIGNED16')}</span>}
      </h2>
      {error ? (
        <table className="kv">
          <tbody>
            <tr>
              <th>Error</th>
              <td data-testid="fault-name">
                <span className="mono">{error.display ?? error.code_hex}</span> {error.name}
              </td>
            </tr>
            <tr>
              <th>Cause</th>
              <td data-testid="fault-cause">{error.cause ?? '—'}</td>
            </tr>
            <tr>
              <th>Remedy</th>
              <td data-testid="fault-remedy">{error.remedy ?? '—'}</td>
            </tr>
            {error.section && (
              <tr>
                <th>Reference</th>
                <td className="muted">{error.section}</td>
              </tr>
            )}
          </tbody>
        </table>
      ) : (
        <div className="muted">The drive reports a fault but the profile has no entry for this code.</div>
      )}
      <div className="muted small">Remove the cause, then press Fault reset.</div>
    </section>
  );
}

export function OverviewPage({ sid }: PageProps) {
  const list = useObservable(sessions);
  const session = list?.find((s) => s.id === sid) ?? null;
  const source = liveSession(sid);
  const live = useObservable(source);
  const ws = useObservable(socketStatus);
  const [busy, setBusy] = useState<StateCommand | null>(null);
  const gate = useWriteGate(sid);
  const state = live.state;
  /** Why a command is refused now (no control, no dead-man), or null. */
  const blockedFor = (c: CommandDef): string | null => (ENERGISING.has(c.command) ? gate.energise : gate.write);

  // Subscribe for live values, and load the state once so the page is complete at once.
  useEffect(() => {
    const unsub = socket.subscribe(sid);
    let alive = true;
    api.state(sid).then(
      (s) => alive && applyState(sid, s),
      (e: unknown) => alive && notifyError(e),
    );
    return () => {
      alive = false;
      unsub();
    };
  }, [sid]);

  // Without the socket, poll once a second rather than show frozen values.
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

  async function run(c: CommandDef) {
    setBusy(c.command);
    const before = source.get().state?.state ?? null;
    try {
      const after = await api.command(sid, c.command, c.label);
      applyState(sid, after);
      // A CiA 402 device ignores a command that has no transition from its state (CiA 402-2
      // table 29); say so instead of leaving the person wondering whether the click worked.
      const goal = c.command === 'enable' || c.command === 'disable';
      if (!goal && before !== null && after.state === before) {
        notify({
          kind: 'warning',
          title: `${c.label}: the drive stayed in ${after.state}`,
          message: `the drive took no transition for ${c.label} (${c.transitions}) from ${after.state}`,
          detail: null,
          hint: 'the blue arrows in the state diagram are the transitions possible from the current state',
        });
      }
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  }

  if (list !== null && !session) {
    return (
      <div className="empty" data-testid="no-session">
        Session <span className="mono">{sid}</span> is not open. <a href="#/connect">Open it on the Connect page.</a>
      </div>
    );
  }

  const stateName = state?.state ?? session?.state ?? null;
  const inFault = stateName === 'Fault' || stateName === 'Fault reaction active';
  const stale = ws.status !== 'open';

  return (
    <div className="stack">
      <ControlNote
        sid={sid}
        energise
        what={gate.write ? 'The state commands are disabled; Quick stop always works' : 'Enable, Switch on and Enable operation are disabled until it is bound'}
      />
      <div className="command-bar" data-testid="command-bar">
        <div className="command-state">
          <span className="muted">State</span>
          <span data-testid="drive-state" className="drive-state">
            <StatePill state={stateName} />
          </span>
          {state && (
            <span className="mono muted" title="statusword 6041h">
              SW {state.statusword_hex}
            </span>
          )}
          {stale && <span className="badge badge-warn" title="WebSocket down: values polled once a second">polled</span>}
        </div>
        <div className="command-buttons">
          {SHORTCUTS.map((c) => (
            <button
              key={c.command}
              type="button"
              className={c.command === 'enable' ? 'go' : ''}
              data-testid={`cmd-${c.command}`}
              title={blockedFor(c) ?? c.transitions}
              disabled={busy !== null || blockedFor(c) !== null}
              onClick={() => void run(c)}
            >
              {busy === c.command ? `${c.label}…` : c.label}
            </button>
          ))}
          <span className="sep" />
          {COMMANDS.map((c) => (
            <button
              key={c.command}
              type="button"
              className="small-btn"
              data-testid={`cmd-${c.command}`}
              title={blockedFor(c) ?? c.transitions}
              disabled={busy !== null || blockedFor(c) !== null}
              onClick={() => void run(c)}
            >
              {c.label}
            </button>
          ))}
          <span className="sep" />
          {/* Quick stop is never disabled: stopping must not wait for another command. */}
          <button
            type="button"
            className="danger"
            data-testid="cmd-quick_stop"
            title={QUICK_STOP.transitions}
            onClick={() => void run(QUICK_STOP)}
          >
            Quick stop
          </button>
        </div>
      </div>

      {inFault && <FaultCard error={state?.error ?? null} code={state?.error_code ?? null} />}

      <div className="overview-grid">
        <div className="stack">
          {session && <IdentityCard session={session} />}
          {session && <ReportCard sid={sid} />}
          <section className="card" data-testid="live">
            <h2>
              Live values
              <span className="h2-side mono muted" data-testid="mode">
                mode (6061h) {state?.mode ?? '—'} · {modeName(state?.mode, state?.mode_name)}
              </span>
            </h2>
            {state ? <LiveValues state={state} /> : <div className="muted">waiting for the drive…</div>}
            <LivePlot source={source} positionUnit={state?.position_unit ?? 'raw'} velocityUnit={state?.velocity_unit ?? 'raw'} />
          </section>
        </div>
        <div className="stack">
          <section className="card">
            <h2>
              State machine <span className="h2-side muted">CiA 402-2 §6.2</span>
            </h2>
            <StateDiagram state={stateName} />
          </section>
          <section className="card">
            <h2>
              Statusword <span className="h2-side muted">6041h</span>
            </h2>
            {state ? <StatuswordTable statusword={state.statusword} bits={state.bits} /> : <div className="muted">—</div>}
          </section>
        </div>
      </div>
    </div>
  );
}
