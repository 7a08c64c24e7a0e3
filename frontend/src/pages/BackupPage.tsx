/**
 * Backup & restore, per drive (docs/api.md "Backup, compare, restore (issue 5)"; DESIGN.md
 * "The browser UI"): take a backup with a label and a note, the drive's backup history
 * (download, upload, edit the note), compare any two of live drive / profile defaults /
 * backups, restore through a preflight-checked wizard, and the session's audit log.
 *
 * DESIGN.md "Rules that hold everywhere": backups are written atomically and never
 * overwritten (here only their label and note change), and a restore reports every item and
 * stores to non-volatile memory only after it verified.
 */
import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import { backupApi } from '../api/client';
import type { BackupInfo, RestoreReport } from '../api/types';
import { AuditLog } from '../components/backup/AuditLog';
import { BackupHistory, type HistoryScope } from '../components/backup/BackupHistory';
import { type CompareAsk, DiffViewer } from '../components/backup/DiffViewer';
import { RestoreWizard } from '../components/backup/RestoreWizard';
import { TakeBackup } from '../components/backup/TakeBackup';
import '../components/backup/backup.css';
import { FailureBox } from '../components/FailureBox';
import { driveKeyOf, sameDrive, serialText } from '../lib/backupHistory';
import { type Failure, failureOf } from '../lib/codes';
import { useSessionInfo, useSessionProfile } from '../state/profileCache';
import type { PageProps } from './registry';

export function BackupPage({ sid }: PageProps) {
  const { info, error: infoError } = useSessionInfo(sid);
  const profileId = info?.profile_id ?? null;
  const { profile } = useSessionProfile(info);
  const errors = useMemo(() => profile?.error_list ?? [], [profile]);
  const groups = profile?.groups ?? [];

  const [scope, setScope] = useState<HistoryScope>('drive');
  const [backups, setBackups] = useState<BackupInfo[] | null>(null);
  const [loading, setLoading] = useState(false);
  const [listFailure, setListFailure] = useState<Failure | null>(null);
  /** The drive's key, once known (from the session or a backup of the same drive). */
  const [driveKey, setDriveKey] = useState<string | null>(null);
  const [highlight, setHighlight] = useState<string | null>(null);
  const [ask, setAsk] = useState<CompareAsk | null>(null);
  const [restoreId, setRestoreId] = useState<string | null>(null);
  const [driveChanged, setDriveChanged] = useState(0);
  const askSeq = useRef(0);
  const loadSeq = useRef(0);

  const sessionKey = (info as { drive_key?: string | null } | null)?.drive_key ?? null;
  const key = sessionKey ?? driveKey;

  const load = useCallback(async () => {
    if (!info) return;
    const my = ++loadSeq.current;
    setLoading(true);
    try {
      let list: BackupInfo[];
      if (scope === 'all') list = await backupApi.list({});
      else if (scope === 'profile') list = await backupApi.list({ profile: info.profile_id });
      else if (key) list = await backupApi.list({ drive: key });
      else {
        // The server does not say which drive key this session has: find this drive's
        // backups by their identity and learn the key from them.
        list = (await backupApi.list({ profile: info.profile_id })).filter((b) => sameDrive(b.identity, info.identity));
        const learnt = driveKeyOf(info, list);
        if (learnt && my === loadSeq.current) setDriveKey(learnt);
      }
      if (my === loadSeq.current) {
        setBackups(list);
        setListFailure(null);
      }
    } catch (e) {
      if (my === loadSeq.current) setListFailure(failureOf(e, 'List the backups', errors));
    } finally {
      if (my === loadSeq.current) setLoading(false);
    }
    // info changes identity often (socket pushes); its id, profile and identity matter.
  }, [scope, key, info?.id, info?.profile_id, info?.identity.serial, errors]);

  useEffect(() => {
    void load();
  }, [load]);

  const compare = (a: string, b: string) => setAsk({ a, b, nonce: ++askSeq.current });

  function taken(b: BackupInfo) {
    if (info && sameDrive(b.identity, info.identity)) setDriveKey(b.drive_key);
    setHighlight(b.id);
    void load();
  }

  function uploaded(b: BackupInfo) {
    setHighlight(b.id);
    // A file of another drive is not in "this drive"'s list: show all of them.
    const mine = info ? (key ? b.drive_key === key : sameDrive(b.identity, info.identity)) : false;
    if (!mine && scope === 'drive') setScope(b.profile_id === profileId ? 'profile' : 'all');
    else void load();
  }

  function finished(r: RestoreReport | null) {
    if (r?.pre_backup) setHighlight(r.pre_backup);
    setDriveChanged((n) => n + 1);
    void load();
  }

  if (infoError && !info) return <FailureBox f={failureOf(infoError, `Load session ${sid}`)} testid="backup-page-failure" />;
  if (!info) return <div className="muted">Loading the session…</div>;

  const scopeLabels: Record<HistoryScope, string> = {
    drive: `This drive (serial ${serialText(info.identity)})`,
    profile: `All drives with profile ${info.profile_id}`,
    all: 'All backups',
  };
  const list = backups ?? [];

  return (
    <div className="stack" data-testid="backup-page">
      <TakeBackup sid={sid} errors={errors} onTaken={taken} onCompare={(b) => compare('drive', `backup:${b.id}`)} />
      <BackupHistory
        backups={backups}
        loading={loading}
        failure={listFailure}
        scope={scope}
        scopeLabels={scopeLabels}
        highlight={highlight}
        errors={errors}
        onScope={setScope}
        onRefresh={() => void load()}
        onChanged={(b) => {
          setBackups((l) => (l ? l.map((x) => (x.id === b.id ? b : x)) : l));
          setHighlight(b.id);
        }}
        onUploaded={uploaded}
        onCompare={(b) => compare('drive', `backup:${b.id}`)}
        onRestore={(b) => {
          setRestoreId(b.id);
          document.querySelector('[data-testid="restore-wizard"]')?.scrollIntoView({ block: 'start', behavior: 'smooth' });
        }}
      />
      <DiffViewer sid={sid} profileId={profileId} backups={list} groups={groups} errors={errors} ask={ask} refreshNonce={driveChanged} />
      <RestoreWizard
        sid={sid}
        profileId={profileId}
        backups={list}
        selected={restoreId}
        errors={errors}
        onSelect={setRestoreId}
        onShowBackup={(bid) => {
          setHighlight(bid);
          document.querySelector(`[data-backup-id="${CSS.escape(bid)}"]`)?.scrollIntoView({ block: 'center', behavior: 'smooth' });
        }}
        onComparePre={(bid) => compare('drive', `backup:${bid}`)}
        onFinished={finished}
      />
      <AuditLog sid={sid} errors={errors} refreshNonce={driveChanged} />
    </div>
  );
}
