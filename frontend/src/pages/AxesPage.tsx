/**
 * All axes at a glance (issue 48): every open session's drive in one table, with its CiA 402
 * state, actual position and velocity (raw in drive units beside the engineering value, as
 * the Overview shows them), the motion servodesk runs, the active alarm (603Fh as the
 * profile names it), the last backup (when, complete or not), the protection against a lost
 * operator (GET .../control `protection`) and who holds control. A row opens that drive's
 * Overview.
 *
 * Sources, no polling: the shared WebSocket (this page subscribes to every session: `state`
 * at the server's live rate, `motion`, and `control` which every socket gets), one GET
 * .../control and GET .../motion per session when the page opens, and one GET /backups,
 * read again when a backup of a drive finishes (its `progress` message reaches 1).
 */
import { useEffect, useState } from 'react';
import type { BackupInfo, PlantBackupReport, SessionInfo } from '../api/types';
import { backupApi, operationApi } from '../api/client';
import { me, rightBlocked } from '../api/auth';
import { StatePill } from '../components/StatePill';
import { operationLive, setMotion, startOperationStore } from '../components/operation/operationStore';
import { alarmText, backupCompleteness, controlCell, lastBackup, protectionText } from '../lib/axes';
import { formatTime } from '../lib/backupHistory';
import { modeName } from '../lib/cia402';
import { formatEngineering } from '../lib/format';
import { useControl } from '../state/control';
import { notifyError } from '../state/notify';
import { useObservable } from '../state/observable';
import { navigate, routeHref } from '../state/router';
import { liveSession, sessions, socket } from '../state/store';
import type { PageProps } from './registry';
import './axes.css';

function Value({ raw, rawUnit, eng, unit, testid }: { raw: number | null | undefined; rawUnit: string | null | undefined; eng: number | null | undefined; unit: string | null | undefined; testid: string }) {
  return (
    <td className="num" data-testid={testid}>
      <span className="mono">{raw ?? '—'}</span> <span className="unit">{rawUnit ?? ''}</span>
      {eng !== null && eng !== undefined && <div className="mono muted small">{formatEngineering(eng, unit)}</div>}
    </td>
  );
}

function AxisRow({ session, backup, myUser }: { session: SessionInfo; backup: BackupInfo | null; myUser: string | null }) {
  const sid = session.id;
  const state = useObservable(liveSession(sid)).state;
  const motion = useObservable(operationLive(sid)).motion;
  const control = useControl(sid);
  const stateName = state?.state ?? session.state;
  const alarm = alarmText(state);
  const holder = controlCell(control, myUser);
  const name = session.identity.device_name || session.profile_name;
  return (
    <tr
      className="axes-row"
      data-testid={`axis-row-${sid}`}
      data-state={stateName}
      data-stop-all={holder.stoppedByStopAll ? 'true' : 'false'}
      onClick={() => navigate('overview', sid)}
      title={`Open ${sid} (Overview)`}
    >
      <td>
        <a href={routeHref('overview', sid)} className="mono" data-testid={`axis-link-${sid}`} onClick={(e) => e.stopPropagation()}>
          {sid}
        </a>
        <div className="muted small">
          {name} · {session.fieldbus}
          {session.simulated ? ' · SIM' : ''}
        </div>
      </td>
      <td data-testid={`axis-state-${sid}`}>
        <StatePill state={stateName} />
        <div className="muted small">{modeName(state?.mode, state?.mode_name)}</div>
      </td>
      <Value testid={`axis-position-${sid}`} raw={state?.position} rawUnit={state?.position_raw_unit} eng={state?.position_eng} unit={state?.position_unit} />
      <Value testid={`axis-velocity-${sid}`} raw={state?.velocity} rawUnit={state?.velocity_raw_unit} eng={state?.velocity_eng} unit={state?.velocity_unit} />
      <td data-testid={`axis-motion-${sid}`} data-active={motion?.active ? 'true' : 'false'} data-motion={motion?.state ?? 'idle'}>
        {motion?.active ? <span className="badge badge-go">{motion.kind} running</span> : motion && motion.state !== 'idle' ? <span className="muted">{motion.kind ?? 'motion'} {motion.state}</span> : <span className="muted">—</span>}
      </td>
      <td data-testid={`axis-alarm-${sid}`} className={alarm ? 'bad' : 'muted'} title={state?.error?.cause ?? undefined}>
        {alarm ?? 'none'}
      </td>
      <td data-testid={`axis-backup-${sid}`}>
        {backup ? (
          <>
            <span className="mono">{formatTime(backup.time)}</span>
            <div className={`small ${backup.complete === false || backup.unreadable?.length ? 'warn-text' : 'muted'}`}>{backupCompleteness(backup)}</div>
          </>
        ) : (
          <span className="muted">none</span>
        )}
      </td>
      <td data-testid={`axis-protection-${sid}`} className="small" title={control.protection?.summary ?? 'read with who holds control'}>
        {protectionText(control.protection)}
      </td>
      <td data-testid={`axis-control-${sid}`} className={holder.stoppedByStopAll ? 'mono' : 'mono muted'}>
        {holder.text}
      </td>
    </tr>
  );
}

/**
 * "Back up every drive" (issue 50): one request backs up every open drive, read at once
 * (POST /backups/plant); the Last backup column follows by the `progress` messages. The line
 * after it says how many were saved, in what time, and names each drive that failed and why.
 */
function BackUpAll({ count, onDone }: { count: number; onDone: () => void }) {
  const [busy, setBusy] = useState(false);
  const [report, setReport] = useState<PlantBackupReport | null>(null);
  const blocked = rightBlocked('backup');
  async function run() {
    setBusy(true);
    setReport(null);
    try {
      setReport(await backupApi.plant({ label: 'all drives', note: '' }));
      // Every backup is saved now (each also says so in a last `progress`): the list again.
      onDone();
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(false);
    }
  }
  const failed = report?.items.filter((i) => !i.ok) ?? [];
  return (
    <div className="axes-backup" data-testid="axes-backup">
      <button type="button" onClick={() => void run()} disabled={busy || blocked !== null} title={blocked ?? 'Read every open drive\'s parameters at once and keep a backup of each'} data-testid="axes-backup-all">
        {busy ? `Backing up ${count} drives…` : 'Back up every drive'}
      </button>
      {report && (
        <span className={failed.length ? 'pdo-over-text small' : 'small'} data-testid="axes-backup-result" data-saved={report.saved} data-failed={report.failed}>
          {' '}
          {report.saved} of {report.items.length} backed up in {report.duration_s.toFixed(1)} s
          {failed.map((i) => (
            <span key={i.session} data-testid={`axes-backup-failed-${i.session}`}>
              {' '}
              · {i.session}: {i.error}
              {i.hint ? ` (${i.hint})` : ''}
            </span>
          ))}
        </span>
      )}
    </div>
  );
}

export function AxesPage(_props: PageProps) {
  const list = useObservable(sessions);
  const who = useObservable(me);
  const [backups, setBackups] = useState<BackupInfo[]>([]);
  const [backupsAt, setBackupsAt] = useState(0);
  const ids = (list ?? []).map((s) => s.id).join('\n');

  // Live state, motion and control of every drive: one subscription each on the shared socket.
  useEffect(() => {
    startOperationStore();
    const sids = ids ? ids.split('\n') : [];
    const unsubs = sids.map((sid) => socket.subscribe(sid));
    let alive = true;
    for (const sid of sids) {
      operationApi.motion(sid).then(
        (m) => alive && setMotion(sid, m),
        () => undefined,
      );
    }
    return () => {
      alive = false;
      for (const u of unsubs) u();
    };
  }, [ids]);

  // The backups: once, and again when a backup of any drive finishes.
  useEffect(() => {
    let alive = true;
    backupApi.list({}).then(
      (b) => alive && setBackups(b),
      (e: unknown) => alive && notifyError(e),
    );
    return () => {
      alive = false;
    };
  }, [backupsAt]);
  useEffect(
    () =>
      socket.on('progress', (m) => {
        if (m.operation === 'backup' && m.fraction >= 1) setBackupsAt(Date.now());
      }),
    [],
  );

  if (list === null) return <div className="muted">Loading the sessions…</div>;
  if (list.length === 0) {
    return (
      <div className="empty" data-testid="axes-empty">
        No drive session is open. <a href={routeHref('connect')}>Open one on the Connect page.</a>
      </div>
    );
  }
  return (
    <section className="card">
      <BackUpAll count={list.length} onDone={() => setBackupsAt(Date.now())} />
      <table className="grid axes-table" data-testid="axes-table">
        <thead>
          <tr>
            <th>Drive</th>
            <th>State</th>
            <th className="num" title="actual position 6064h: raw in drive units, engineering below">
              Position
            </th>
            <th className="num" title="actual velocity 606Ch: raw in drive units, engineering below">
              Velocity
            </th>
            <th>Motion</th>
            <th title="603Fh error code, as the profile's alarm table names it">Alarm</th>
            <th>Last backup</th>
            <th title="what stops the axis when its operator is lost">Protection</th>
            <th title="who holds control; STOP ALL stops the axes marked you">Control</th>
          </tr>
        </thead>
        <tbody>
          {list.map((s) => (
            <AxisRow key={s.id} session={s} backup={lastBackup(s, backups)} myUser={who?.user ?? null} />
          ))}
        </tbody>
      </table>
      <div className="muted small">
        Click a row to open the drive. STOP ALL in the header (or Esc) quick-stops every axis whose control column says “you”.
      </div>
    </section>
  );
}
