/**
 * "Take a backup": label and note, a progress bar fed by the WebSocket's `progress` messages
 * (operation "backup", docs/api.md), and the result (how many entries, the file's hash).
 */
import { type FormEvent, useState } from 'react';
import { backupApi } from '../../api/client';
import type { BackupInfo, ErrorInfo } from '../../api/types';
import { type Failure, failureOf } from '../../lib/codes';
import { backupTitle } from '../../lib/backupHistory';
import { watchBackupProgress } from '../../lib/backupProgress';
import { FailureBox } from '../FailureBox';
import { ProgressBar } from '../ProgressBar';
import { UnreadableList, objectsText } from './UnreadableList';

interface Run {
  fraction: number | null;
  message: string | null;
}

export function TakeBackup({
  sid,
  errors,
  onTaken,
  onCompare,
}: {
  sid: string;
  errors: readonly ErrorInfo[];
  onTaken: (b: BackupInfo) => void;
  onCompare: (b: BackupInfo) => void;
}) {
  const [label, setLabel] = useState('');
  const [note, setNote] = useState('');
  const [run, setRun] = useState<Run | null>(null);
  const [result, setResult] = useState<BackupInfo | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);

  async function take(e: FormEvent) {
    e.preventDefault();
    setRun({ fraction: null, message: 'starting…' });
    setResult(null);
    setFailure(null);
    const watch = watchBackupProgress(sid, 'backup', (m) => setRun({ fraction: m.fraction, message: m.message }));
    try {
      await watch.ready;
      const b = await backupApi.take(sid, { label: label.trim(), note });
      setResult(b);
      setLabel('');
      setNote('');
      onTaken(b);
    } catch (err) {
      setFailure(failureOf(err, 'Take a backup', errors));
    } finally {
      watch.close();
      setRun(null);
    }
  }

  return (
    <section className="card" data-testid="take-backup">
      <h2>Take a backup</h2>
      <form className="bk-form" onSubmit={take}>
        <label className="label-field">
          Label
          <input
            data-testid="backup-label"
            value={label}
            onChange={(e) => setLabel(e.target.value)}
            placeholder="e.g. after tuning"
            maxLength={120}
            disabled={run !== null}
          />
        </label>
        <label className="note-field">
          Note
          <input data-testid="backup-note" value={note} onChange={(e) => setNote(e.target.value)} placeholder="what was done, by whom (optional)" disabled={run !== null} />
        </label>
        <button type="submit" className="primary" data-testid="backup-take" disabled={run !== null}>
          {run ? 'Backing up…' : 'Take backup'}
        </button>
      </form>
      <div className="muted small" style={{ marginTop: 4 }}>
        Reads every stored parameter of the drive (process values are left out) into a new file; backups are never overwritten.
      </div>
      {run && (
        <div style={{ marginTop: 8 }}>
          <ProgressBar fraction={run.fraction} label={run.message ?? (run.fraction === null ? 'reading…' : `${Math.round(run.fraction * 100)} %`)} testid="backup-progress" />
        </div>
      )}
      {result && (
        <div className={result.complete ? 'bk-ok' : 'bk-warn'} data-testid="backup-result" data-complete={result.complete ? 'true' : 'false'} style={{ marginTop: 8 }}>
          <div className="bk-row">
            <span>
              <strong>{result.complete ? 'Backup taken:' : 'Incomplete backup taken:'}</strong> {backupTitle(result)} ·{' '}
              <span className="mono" data-testid="backup-result-entries">
                {result.entries}
              </span>{' '}
              entries · profile <span className="mono">{result.profile_id}</span> · file <span className="mono">{result.file}</span> ·{' '}
              <span className="mono muted" title={`SHA-256 of the backup file: ${result.sha256}`}>
                sha256 {result.sha256.slice(0, 12)}…
              </span>
            </span>
            <button type="button" className="small-btn" onClick={() => onCompare(result)} data-testid="backup-result-compare">
              Compare with the live drive
            </button>
          </div>
          <UnreadableList
            items={result.unreadable}
            headline={`${objectsText(result.unreadable.length)} could not be read and ${result.unreadable.length === 1 ? 'is' : 'are'} not in this backup: restoring it cannot set ${result.unreadable.length === 1 ? 'it' : 'them'}.`}
            testid="backup-result-unreadable"
          />
        </div>
      )}
      {failure && (
        <div style={{ marginTop: 8 }}>
          <FailureBox f={failure} testid="backup-failure" />
        </div>
      )}
    </section>
  );
}
