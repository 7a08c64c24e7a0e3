/**
 * Cyclic process data (docs/pdo.md "REST": /pdo/cyclic): start and stop the session's SYNC
 * producer and PDO exchange at a chosen period, and its status: frames per second, decode
 * errors and the rate of each PDO. The values themselves are shown next to the mapped objects
 * in the PDO tables.
 */
import { useCallback, useEffect, useState } from 'react';
import { pdoApi } from '../../api/pdo';
import type { ErrorInfo, PdoApplyReport, PdoCyclicStatus, PdoIdleFix, PdoRate } from '../../api/types';
import { type Failure, failureOf } from '../../lib/codes';
import { type SyncMode, dcCycleProblem, syncText } from '../../lib/sync';
import { type Observable, useObservable } from '../../state/observable';
import { ConfirmDialog } from '../ConfirmDialog';
import { ControlNote, useWriteGate } from '../ControlNote';
import { FailureBox } from '../FailureBox';
import { NumberBox, decimalParser } from './fields';
import type { PdoLive } from './pdoLive';

const DEFAULT_PERIOD_MS = 10;

function RateRows({ rates, live, dir }: { rates: readonly PdoRate[]; live: Record<string, number>; dir: string }) {
  return (
    <>
      {rates.map((r) => {
        const hz = live[r.name] ?? r.rate_hz;
        const sent = dir === 'to the drive';
        return (
          <tr key={`${dir}-${r.name}`} data-testid={`pdo-rate-${r.name}`}>
            <td>{r.name}</td>
            <td className="muted small">{dir}</td>
            <td className="mono">{r.cob_id_hex ?? (r.cob_id !== null ? `0x${r.cob_id.toString(16).toUpperCase().padStart(3, '0')}` : '—')}</td>
            <td className="num mono">{r.count}</td>
            <td className="num mono">{hz !== null && hz !== undefined ? hz.toFixed(1) : sent ? <span className="muted small">with each SYNC</span> : '—'}</td>
          </tr>
        );
      })}
    </>
  );
}

/** A fix of the silent TPDOs the user is asked to confirm. */
interface FixAsk {
  names: string[];
  fix: PdoIdleFix;
}

/** "TPDO1", "TPDO1 and TPDO2", "TPDO1, TPDO2 and TPDO3". */
function namesText(names: readonly string[]): string {
  return names.length < 2 ? (names[0] ?? '') : `${names.slice(0, -1).join(', ')} and ${names[names.length - 1]}`;
}

/** The PDO change a fix makes: the TPDOs keep their entries, only their transmission changes. */
async function applyFix(sid: string, ask: FixAsk): Promise<PdoApplyReport> {
  const view = await pdoApi.view(sid);
  const pdos = ask.names.map((name) => {
    const p = view.pdos.find((x) => x.direction === 'tx' && x.name === name);
    if (!p) throw new Error(`${name} is no longer in the drive's PDO configuration`);
    return {
      direction: 'tx' as const,
      number: p.number,
      entries: p.entries.map((e) => ({ index: e.index, subindex: e.subindex, bits: e.bits })),
      ...(ask.fix.transmission_type !== null ? { transmission_type: ask.fix.transmission_type } : {}),
      ...(ask.fix.event_timer !== null ? { event_timer: ask.fix.event_timer } : {}),
    };
  });
  return pdoApi.apply(sid, { dry_run: false, pdos });
}

export function CyclicPanel({
  sid,
  live,
  errors,
  onStatus,
  onApplied,
  driveTelegram = null,
  onStarted,
}: {
  sid: string;
  live: Observable<PdoLive>;
  errors: readonly ErrorInfo[];
  onStatus?: (s: PdoCyclicStatus) => void;
  /** A fix of a silent TPDO changed the mapping: the page shows the drive's new one. */
  onApplied?: (r: PdoApplyReport) => void;
  /** PROFINET: the telegram the drive has now (P922), the choice's starting value. */
  driveTelegram?: number | null;
  /** Cyclic data started: on PROFINET the drive's telegram may have changed with it. */
  onStarted?: (s: PdoCyclicStatus) => void;
}) {
  const [ask, setAsk] = useState<FixAsk | null>(null);
  const [fixing, setFixing] = useState(false);
  const [status, setStatus] = useState<PdoCyclicStatus | null>(null);
  const [period, setPeriod] = useState(DEFAULT_PERIOD_MS);
  const [sync, setSync] = useState<SyncMode>('freerun');
  // PROFINET: the telegram servodesk's IO AR is set up with (the expected submodule; the
  // drive's P922 follows, as from a PLC's configuration, 004 §20.1.1). Starts as the drive's.
  const [telegram, setTelegram] = useState<number | null>(driveTelegram);
  const [busy, setBusy] = useState(false);
  const [failure, setFailure] = useState<Failure | null>(null);
  // Starting, changing and stopping the cyclic data change the drive: they need control.
  const noControl = useWriteGate(sid).write;
  const l = useObservable(live);

  const got = useCallback(
    (s: PdoCyclicStatus) => {
      setStatus(s);
      onStatus?.(s);
    },
    [onStatus],
  );

  const read = useCallback(async () => {
    try {
      got(await pdoApi.cyclic(sid));
      setFailure((f) => (f?.action === 'Read the cyclic data status' ? null : f));
    } catch (e) {
      setFailure(failureOf(e, 'Read the cyclic data status', errors));
    }
  }, [sid, got, errors]);

  useEffect(() => {
    void read();
  }, [read]);

  // While it runs, the counters change: read them every second (the values come by socket).
  const running = status?.running ?? false;
  useEffect(() => {
    if (!running) return;
    const t = setInterval(() => void read(), 1000);
    return () => clearInterval(t);
  }, [running, read]);

  useEffect(() => {
    if (status?.running && status.sync_period_ms) setPeriod(status.sync_period_ms);
    if (status?.running && status.sync) setSync(status.sync);
    if (status?.running && status.telegram) setTelegram(status.telegram);
    // Only when the server's period, sync or telegram changes, not on every poll.
  }, [status?.running, status?.sync_period_ms, status?.sync, status?.telegram]);

  // A link with a fixed set of cycles (PROFINET: 1 ms send clock x reduction ratio): the
  // period is one of them, the nearest to what was typed.
  const periods = status?.periods_ms ?? null;
  useEffect(() => {
    if (!periods || periods.length === 0 || periods.includes(period)) return;
    setPeriod(periods.reduce((a, b) => (Math.abs(b - period) < Math.abs(a - period) ? b : a)));
  }, [periods?.join(','), period]);

  useEffect(() => {
    if (!running && driveTelegram !== null) setTelegram(driveTelegram);
    // The drive's telegram as the page read it; a running AR's telegram wins (above).
  }, [driveTelegram]);

  async function start() {
    setBusy(true);
    setFailure(null);
    try {
      const offer = status?.telegrams ?? null;
      const s = await pdoApi.startCyclic(sid, {
        sync_period_ms: period,
        outputs: false,
        sync,
        ...(offer && telegram !== null ? { telegram } : {}),
      });
      got(s);
      onStarted?.(s);
    } catch (e) {
      setFailure(failureOf(e, 'Start cyclic data', errors));
    } finally {
      setBusy(false);
    }
  }

  async function stop() {
    setBusy(true);
    setFailure(null);
    try {
      got(await pdoApi.stopCyclic(sid));
    } catch (e) {
      setFailure(failureOf(e, 'Stop cyclic data', errors));
    } finally {
      setBusy(false);
    }
  }

  async function fix(a: FixAsk) {
    setFixing(true);
    setFailure(null);
    try {
      const r = await applyFix(sid, a);
      onApplied?.(r);
      if (!r.ok) setFailure(failureOf(new Error(r.error ?? 'the drive refused the change'), `Change ${namesText(a.names)}`, errors));
      setAsk(null);
      void read();
    } catch (e) {
      setFailure(failureOf(e, `Change ${namesText(a.names)}`, errors));
      setAsk(null);
    } finally {
      setFixing(false);
    }
  }

  /** TPDOs that send nothing because of their configuration (the server says why). */
  const idle = (status?.tx_pdos ?? []).filter((r) => r.idle);
  const offersDc = status?.sync_modes?.includes('dc') ?? false;
  const telegrams = status?.telegrams ?? null;
  const chosen = telegrams?.find((t) => t.number === telegram) ?? null;
  const periodChanged =
    running &&
    (status?.sync_period_ms !== period || (status?.sync ?? 'freerun') !== sync || (telegrams !== null && status?.telegram !== telegram));
  const cycleProblem = sync === 'dc' ? dcCycleProblem(period, status?.dc_cycle_ns) : null;
  const unavailable = status?.unavailable ?? null;
  const clock = syncText(status?.sync, status?.sync_period_ms);
  const rates = [...(status?.rx_pdos ?? []), ...(status?.tx_pdos ?? [])];
  const link = status?.link ?? null;
  return (
    <section className="card" data-testid="pdo-cyclic-card">
      <h2>
        Cyclic data
        <span className="h2-side small">
          {running && link && link.state !== 'ok' ? (
            // The exchange runs but the line does not answer as it should: say so rather
            // than "running" (issue 46: a stale "Operation enabled" under "running").
            <span className="pdo-over-text" data-testid="pdo-cyclic-state" data-running="true" data-link={link.state} title={link.reason ?? undefined}>
              {link.state}
            </span>
          ) : running ? (
            <span className="pdo-ok-text" data-testid="pdo-cyclic-state" data-running="true">
              running
            </span>
          ) : (
            <span className="muted" data-testid="pdo-cyclic-state" data-running="false">
              stopped
            </span>
          )}
          {!l.connected && <span className="muted"> · live socket connecting…</span>}
        </span>
      </h2>
      <div className="bk-row">
        <label className="pdo-inline small muted">
          {periods ? 'Cycle' : sync === 'dc' ? 'SYNC0 cycle' : 'SYNC period'}
          {periods ? (
            <select
              value={period}
              onChange={(e) => setPeriod(Number(e.target.value))}
              data-testid="pdo-cyclic-period-choice"
              title="The IO cycle: the 1 ms send clock times a reduction ratio (RT_CLASS_1)"
            >
              {periods.map((p) => (
                <option key={p} value={p}>
                  {p}
                </option>
              ))}
            </select>
          ) : (
            <NumberBox
              value={period}
              onChange={setPeriod}
              parse={decimalParser(1, 1000, 2)}
              testid="pdo-cyclic-period"
              label="SYNC period in ms"
              width={60}
              title="1 ms to 1000 ms (0.01 ms steps; DC SYNC0: the drive's cycles)"
            />
          )}
          ms
        </label>
        {offersDc && (
          <label
            className="pdo-inline small muted"
            title="FreeRun: the drive runs its own cycle and takes the data as it comes. DC: the EtherCAT distributed clocks fire the drive's SYNC0 at the period, and the drive samples and applies the data on it (ETG.1020; HIWIN 000 §2.5)."
          >
            Sync
            <select value={sync} onChange={(e) => setSync(e.target.value as SyncMode)} data-testid="pdo-cyclic-sync">
              <option value="freerun">FreeRun</option>
              <option value="dc">DC SYNC0</option>
            </select>
          </label>
        )}
        {telegrams && (
          <label
            className="pdo-inline small muted"
            title="The telegram servodesk's IO AR exchanges: its expected submodule at the connect, as an IO controller's configuration tool sets it up from the GSD file (004 §20.1.1). The drive's P922 follows."
          >
            Telegram
            <select value={telegram ?? ''} onChange={(e) => setTelegram(Number(e.target.value))} data-testid="pdo-cyclic-telegram">
              {telegram === null && <option value="">choose…</option>}
              {telegrams.map((t) => (
                <option key={t.number} value={t.number}>
                  {t.name}
                  {t.number === driveTelegram ? ' (the drive’s now)' : ''}
                </option>
              ))}
            </select>
          </label>
        )}
        {!running && (
          <button
            type="button"
            className="go"
            disabled={busy || unavailable !== null || cycleProblem !== null || noControl !== null}
            title={unavailable ?? cycleProblem ?? noControl ?? undefined}
            onClick={() => void start()}
            data-testid="pdo-cyclic-start"
          >
            Start
          </button>
        )}
        {running && periodChanged && (
          <button
            type="button"
            disabled={busy || cycleProblem !== null || noControl !== null}
            title={cycleProblem ?? noControl ?? undefined}
            onClick={() => void start()}
            data-testid="pdo-cyclic-reconfigure"
          >
            Use {period} ms{offersDc ? (sync === 'dc' ? ' DC' : ' FreeRun') : ''}
            {telegrams && chosen ? `, ${chosen.name}` : ''}
          </button>
        )}
        {running && (
          <button type="button" disabled={busy || noControl !== null} title={noControl ?? undefined} onClick={() => void stop()} data-testid="pdo-cyclic-stop">
            Stop
          </button>
        )}
        {status && (
          <span className="small" data-testid="pdo-cyclic-stats">
            <span className="mono">{status.frames_per_s.toFixed(0)}</span> frames/s
            {clock ? <span data-testid="pdo-cyclic-sync-text"> · {clock}</span> : null}{' '}
            ·{' '}
            <span className={status.decode_errors ? 'pdo-over-text' : ''}>
              <span className="mono">{status.decode_errors}</span> decode errors
            </span>
            {link && (
              <span data-testid="pdo-cyclic-link-counters">
                {' '}
                ·{' '}
                <span className={link.wkc_errors ? 'pdo-over-text' : ''} title="cycles whose working counter fell short (a slave did not take part)">
                  <span className="mono">{link.wkc_errors}</span> WKC errors
                </span>{' '}
                ·{' '}
                <span className={link.missing_frames ? 'pdo-over-text' : ''} title="cycles whose frame did not come back">
                  <span className="mono">{link.missing_frames}</span> missing frames
                </span>
              </span>
            )}
          </span>
        )}
      </div>
      {running && link && link.state !== 'ok' && (
        <div className="bk-warn small" data-testid="pdo-cyclic-link">
          {link.state === 'link lost'
            ? 'Link lost'
            : link.state === 'recovering'
              ? link.ar
                ? 'Link back, the IO AR set up again'
                : 'Link back, bringing the line back to its state'
              : 'Working counter errors'}
          {link.reason ? `: ${link.reason}` : ''}. The greyed values are the last received, not the drive&apos;s present ones.
          {status?.outputs ? ' Motion does not resume by itself: the output image holds a quick stop.' : ''}
        </div>
      )}
      {chosen && !chosen.controlword && (
        <div className="bk-warn small" data-testid="pdo-cyclic-telegram-note">
          {chosen.name} carries no controlword (6040h): the drive follows PROFIdrive&apos;s STW1 over it, so servo on, jog and moves from
          the Operation page need a telegram with the controlword{telegrams?.some((t) => t.controlword) ? ` (${telegrams.filter((t) => t.controlword).map((t) => t.number).join(', ')})` : ''}.
        </div>
      )}
      {cycleProblem !== null && (
        <div className="bk-warn small" data-testid="pdo-cyclic-cycle-problem">
          {period} ms is no SYNC0 cycle of this drive: {cycleProblem}.
        </div>
      )}
      {unavailable !== null ? (
        <div className="bk-warn small" data-testid="pdo-cyclic-unavailable">
          No cyclic data on this link: {unavailable}.
        </div>
      ) : (
        <div className="muted small">Inputs only: the drive's TPDOs are read, no RPDO set-points are sent.</div>
      )}
      {running && idle.length > 0 && (
        <div className="bk-warn small" data-testid="pdo-idle" style={{ marginTop: 6 }}>
          <strong>Nothing arrives from {namesText(idle.map((r) => r.name))}.</strong>
          <ul style={{ margin: '4px 0', paddingLeft: 18 }}>
            {idle.map((r) => (
              <li key={r.name} data-testid={`pdo-idle-${r.name}`}>
                {r.idle?.why}
              </li>
            ))}
          </ul>
          <div className="bk-row">
            <span>Make {idle.length === 1 ? 'it' : 'them'} send:</span>
            {(idle[0]?.idle?.fixes ?? []).map((f, i) => (
              <button
                type="button"
                key={f.label}
                className="small-btn"
                disabled={fixing || noControl !== null}
                title={noControl ?? 'a PDO change: written to the drive, read back and verified; asks first'}
                onClick={() => setAsk({ names: idle.map((r) => r.name), fix: f })}
                data-testid={`pdo-idle-fix-${i}`}
              >
                {idle.length === 1 ? f.label : f.label.replace('send it', 'send them')}…
              </button>
            ))}
          </div>
        </div>
      )}
      <ControlNote sid={sid} what="Start and Stop are disabled" testid="pdo-cyclic-control-note" />
      {ask && (
        <ConfirmDialog
          title={`Change ${namesText(ask.names)}?`}
          confirmLabel={`Change ${namesText(ask.names)}`}
          busy={fixing}
          onCancel={() => setAsk(null)}
          onConfirm={() => void fix(ask)}
          testid="pdo-idle-dialog"
        >
          <p>
            servodesk changes the communication parameters of {namesText(ask.names)} so that the drive will {ask.names.length === 1 ? ask.fix.label : ask.fix.label.replace('send it', 'send them')}:{' '}
            {ask.fix.transmission_type !== null ? `transmission type ${ask.fix.transmission_type}` : `event timer ${ask.fix.event_timer} ms`}. Its mapped objects stay as they are.
          </p>
          <p className="muted small">
            Like any PDO change, the drive goes to pre-operational for the write, the values are read back, and the cyclic data restarts. Save to EEPROM on the Parameters page to keep it after a power cycle.
          </p>
        </ConfirmDialog>
      )}
      {failure && <FailureBox f={failure} testid="pdo-cyclic-failure" />}
      {rates.length > 0 && (
        <table className="grid pdo-rates" data-testid="pdo-rates">
          <thead>
            <tr>
              <th>PDO</th>
              <th />
              <th>COB-ID</th>
              <th className="num">Frames</th>
              <th className="num">Rate (Hz)</th>
            </tr>
          </thead>
          <tbody>
            <RateRows rates={status?.rx_pdos ?? []} live={l.rates} dir="to the drive" />
            <RateRows rates={status?.tx_pdos ?? []} live={l.rates} dir="from the drive" />
          </tbody>
        </table>
      )}
    </section>
  );
}
