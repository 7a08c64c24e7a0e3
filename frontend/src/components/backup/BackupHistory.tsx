/**
 * The backup history of a drive (GET /backups?drive=...): time, label, note (editable; PATCH
 * changes only the metadata, the file never changes), entries, profile, serial; download as
 * JSON, DCF or CSV; upload a JSON backup or DCF file (POST /backups/upload).
 */
import { type ChangeEvent, Fragment, useEffect, useRef, useState } from 'react';
import { backupApi } from '../../api/client';
import type { BackupFormat, BackupInfo, ErrorInfo } from '../../api/types';
import { type Failure, failureOf } from '../../lib/codes';
import { downloadName, formatTime, serialText, uploadProblem } from '../../lib/backupHistory';
import { FailureBox } from '../FailureBox';
import { UnreadableList, objectsText } from './UnreadableList';

export type HistoryScope = 'drive' | 'profile' | 'all';

const FORMATS: readonly BackupFormat[] = ['json', 'dcf', 'csv'];

/** Save a blob as a file through a temporary link (the browser's download). */
function saveBlob(blob: Blob, filename: string): void {
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = filename;
  document.body.appendChild(a);
  a.click();
  a.remove();
  // Give the browser time to start the download before the URL goes.
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

function EditRow({ b, errors, onSaved, onCancel }: { b: BackupInfo; errors: readonly ErrorInfo[]; onSaved: (b: BackupInfo) => void; onCancel: () => void }) {
  const [label, setLabel] = useState(b.label);
  const [note, setNote] = useState(b.note);
  const [busy, setBusy] = useState(false);
  const [failure, setFailure] = useState<Failure | null>(null);
  async function save() {
    setBusy(true);
    setFailure(null);
    try {
      onSaved(await backupApi.patch(b.id, { label: label.trim(), note }));
    } catch (e) {
      setFailure(failureOf(e, 'Save the backup label and note', errors));
      setBusy(false);
    }
  }
  return (
    <>
      <td className="edit-cell">
        <input data-testid="edit-label" value={label} onChange={(e) => setLabel(e.target.value)} maxLength={120} autoFocus />
      </td>
      <td className="edit-cell" colSpan={4}>
        <textarea
          data-testid="edit-note"
          value={note}
          rows={2}
          onChange={(e) => setNote(e.target.value)}
          onKeyDown={(e) => {
            if (e.key === 'Escape') onCancel();
          }}
        />
        {failure && <FailureBox f={failure} testid="edit-failure" />}
      </td>
      <td className="actions">
        <button type="button" className="primary" onClick={() => void save()} disabled={busy} data-testid="edit-save">
          {busy ? 'Saving…' : 'Save'}
        </button>
        <button type="button" onClick={onCancel} disabled={busy}>
          Cancel
        </button>
      </td>
    </>
  );
}

export function BackupHistory({
  backups,
  loading,
  failure,
  scope,
  scopeLabels,
  highlight,
  errors,
  onScope,
  onRefresh,
  onChanged,
  onUploaded,
  onCompare,
  onRestore,
}: {
  backups: readonly BackupInfo[] | null;
  loading: boolean;
  failure: Failure | null;
  scope: HistoryScope;
  scopeLabels: Record<HistoryScope, string>;
  highlight: string | null;
  errors: readonly ErrorInfo[];
  onScope: (s: HistoryScope) => void;
  onRefresh: () => void;
  onChanged: (b: BackupInfo) => void;
  onUploaded: (b: BackupInfo) => void;
  onCompare: (b: BackupInfo) => void;
  onRestore: (b: BackupInfo) => void;
}) {
  const [editing, setEditing] = useState<string | null>(null);
  /** The backup whose unreadable objects are listed under its row. */
  const [lacks, setLacks] = useState<string | null>(null);
  const [busy, setBusy] = useState<string | null>(null);
  const [opFailure, setOpFailure] = useState<Failure | null>(null);
  const [uploaded, setUploaded] = useState<BackupInfo | null>(null);
  const fileRef = useRef<HTMLInputElement>(null);
  const tableRef = useRef<HTMLDivElement>(null);

  // Bring a highlighted backup (just taken, uploaded, or the pre-restore one) into view.
  useEffect(() => {
    if (!highlight) return;
    const row = tableRef.current?.querySelector(`[data-backup-id="${CSS.escape(highlight)}"]`);
    row?.scrollIntoView({ block: 'nearest' });
  }, [highlight, backups]);

  async function download(b: BackupInfo, format: BackupFormat) {
    setBusy(`${b.id}:${format}`);
    setOpFailure(null);
    try {
      const f = await backupApi.download(b.id, format);
      saveBlob(f.blob, f.filename ?? downloadName(b, format));
    } catch (e) {
      setOpFailure(failureOf(e, `Download backup as ${format.toUpperCase()}`, errors));
    } finally {
      setBusy(null);
    }
  }

  async function upload(e: ChangeEvent<HTMLInputElement>) {
    const file = e.target.files?.[0];
    e.target.value = '';
    if (!file) return;
    setOpFailure(null);
    setUploaded(null);
    const problem = uploadProblem(file.name, file.size);
    if (problem) {
      setOpFailure({ action: `Upload ${file.name}`, message: problem, hint: 'choose a servodesk JSON backup or a DCF file', code: null, code_hex: null, meaning: null, protocol: null, info: null });
      return;
    }
    setBusy('upload');
    try {
      const b = await backupApi.upload(file.name, await file.text());
      setUploaded(b);
      onUploaded(b);
    } catch (err) {
      setOpFailure(failureOf(err, `Upload ${file.name}`, errors));
    } finally {
      setBusy(null);
    }
  }

  return (
    <section className="card" data-testid="backup-history">
      <h2>
        History
        <span className="h2-side muted">{backups ? `${backups.length} backup${backups.length === 1 ? '' : 's'}` : ''}</span>
      </h2>
      <div className="bk-row" style={{ marginBottom: 8 }}>
        <label className="bk-row small muted">
          Show
          <select data-testid="history-scope" value={scope} onChange={(e) => onScope(e.target.value as HistoryScope)}>
            {(['drive', 'profile', 'all'] as const).map((s) => (
              <option key={s} value={s}>
                {scopeLabels[s]}
              </option>
            ))}
          </select>
        </label>
        <button type="button" className="small-btn" onClick={onRefresh} disabled={loading} data-testid="history-refresh">
          {loading ? 'Loading…' : 'Refresh'}
        </button>
        <span className="spacer" />
        <span className="upload-btn">
          <input ref={fileRef} type="file" accept=".json,.dcf,application/json,text/plain" onChange={(e) => void upload(e)} data-testid="backup-upload-input" />
          <button type="button" className="small-btn" onClick={() => fileRef.current?.click()} disabled={busy === 'upload'} data-testid="backup-upload" title="A servodesk JSON backup or a DCF file">
            {busy === 'upload' ? 'Uploading…' : 'Upload backup file…'}
          </button>
        </span>
      </div>
      {failure && <FailureBox f={failure} testid="history-failure" />}
      {opFailure && <FailureBox f={opFailure} testid="history-op-failure" />}
      {uploaded && (
        <div className="bk-ok small" data-testid="upload-result">
          Uploaded as backup <span className="mono">{uploaded.id}</span> ({uploaded.entries} entries, profile <span className="mono">{uploaded.profile_id}</span>
          {uploaded.identity.serial != null ? `, serial ${uploaded.identity.serial}` : ''}).
        </div>
      )}
      {backups && backups.length === 0 && !failure && (
        <div className="muted" data-testid="history-empty" style={{ padding: '8px 0' }}>
          No backups {scope === 'drive' ? 'of this drive' : 'here'} yet. Take one, or upload a file.
        </div>
      )}
      {backups && backups.length > 0 && (
        <div className="bk-table-wrap" ref={tableRef}>
          <table className="grid bk-table" data-testid="history-table">
            <thead>
              <tr>
                <th>Time</th>
                <th>Label</th>
                <th>Note</th>
                <th className="num">Entries</th>
                <th>Profile</th>
                <th>Serial</th>
                <th className="num">Actions</th>
              </tr>
            </thead>
            <tbody>
              {backups.map((b) => (
                <Fragment key={b.id}>
                <tr className={b.id === highlight ? 'highlight' : ''} data-testid="history-row" data-backup-id={b.id} data-label={b.label}>
                  <td className="mono nowrap">{formatTime(b.time)}</td>
                  {editing === b.id ? (
                    <EditRow
                      b={b}
                      errors={errors}
                      onCancel={() => setEditing(null)}
                      onSaved={(nb) => {
                        setEditing(null);
                        onChanged(nb);
                      }}
                    />
                  ) : (
                    <>
                      <td data-testid="history-label">{b.label || <span className="muted">—</span>}</td>
                      <td className="note-cell" data-testid="history-note">
                        {b.note || <span className="muted">—</span>}
                      </td>
                      <td className="mono num nowrap" data-testid="history-entries">
                        {b.entries}
                        {!b.complete && (
                          <button
                            type="button"
                            className="badge badge-warn badge-btn"
                            data-testid="history-incomplete"
                            aria-expanded={lacks === b.id}
                            title={`Incomplete: ${objectsText(b.unreadable.length)} could not be read when it was taken (click for the list)`}
                            onClick={() => setLacks(lacks === b.id ? null : b.id)}
                          >
                            incomplete · {b.unreadable.length} unreadable
                          </button>
                        )}
                      </td>
                      <td className="mono small nowrap" title={b.profile_version != null ? `profile version ${b.profile_version}` : undefined}>
                        {b.profile_id}
                      </td>
                      <td className="mono" title={b.identity.device_name ?? undefined}>
                        {serialText(b.identity)}
                      </td>
                      <td className="actions">
                        <span className="dl-group" role="group" aria-label="Download">
                          {FORMATS.map((f) => (
                            <button
                              type="button"
                              key={f}
                              onClick={() => void download(b, f)}
                              disabled={busy !== null}
                              title={`Download as ${f.toUpperCase()}`}
                              data-testid={`download-${f}`}
                            >
                              {busy === `${b.id}:${f}` ? '…' : f.toUpperCase()}
                            </button>
                          ))}
                        </span>
                        <button type="button" onClick={() => setEditing(b.id)} data-testid="history-edit" title="Edit the label and the note">
                          Edit
                        </button>
                        <button type="button" onClick={() => onCompare(b)} data-testid="history-compare" title="Compare the live drive with this backup">
                          Compare
                        </button>
                        <button type="button" onClick={() => onRestore(b)} data-testid="history-restore" title="Restore this backup into the drive">
                          Restore…
                        </button>
                      </td>
                    </>
                  )}
                </tr>
                {lacks === b.id && !b.complete && (
                  <tr data-testid="history-unreadable-row">
                    <td colSpan={7}>
                      <UnreadableList
                        items={b.unreadable}
                        open
                        headline={`This backup is incomplete: ${objectsText(b.unreadable.length)} could not be read when it was taken; restoring it cannot set ${b.unreadable.length === 1 ? 'it' : 'them'}.`}
                        testid="history-unreadable"
                      />
                    </td>
                  </tr>
                )}
                </Fragment>
              ))}
            </tbody>
          </table>
        </div>
      )}
    </section>
  );
}
