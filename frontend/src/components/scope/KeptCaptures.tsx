/**
 * Kept captures of the drive (issue 49, docs/scope.md "Kept captures"; docs/ui.md "Scope"):
 * "Keep capture" stores the scope's captured window (or its whole buffer) in the store with a
 * title and a note, and the list shows the drive's kept captures from every session and
 * gateway. Open shows one in the plot (as an imported recording), CSV downloads it, the
 * Report box attaches it to the drive's commissioning reports, and Delete asks for a reason
 * (the audit log keeps it). Keeping, attaching and deleting need the backup right, as
 * backups do; reading needs only the right to see the drive.
 */
import { useCallback, useEffect, useState } from 'react';
import { rightBlocked } from '../../api/auth';
import { type CaptureInfo, type ScopeRecording, scopeApi } from '../../api/scope';
import { type Failure, failureOf } from '../../lib/codes';
import { ConfirmDialog } from '../ConfirmDialog';
import { FailureBox } from '../FailureBox';
import { saveBlob } from '../pdo/download';
import { MAX_NOTE, MAX_TITLE, capturePeriod, channelsText, keptWhen, noteProblem, reasonProblem, titleProblem, unitText } from './kept';

export function KeptCaptures({
  sid,
  keepWindow: defaultWindow,
  canKeep,
  onOpen,
}: {
  sid: string;
  /** What Keep stores by default: the captured window when one is shown, else the buffer. */
  keepWindow: 'capture' | 'buffer';
  /** Why nothing can be kept now (no samples), or null. */
  canKeep: string | null;
  onOpen: (rec: ScopeRecording, name: string) => void;
}) {
  const [list, setList] = useState<CaptureInfo[] | null>(null);
  const [title, setTitle] = useState('');
  const [note, setNote] = useState('');
  const [which, setWhich] = useState<'capture' | 'buffer'>(defaultWindow);
  const [attach, setAttach] = useState(false);
  const [tried, setTried] = useState(false);
  const [busy, setBusy] = useState<string | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [deleting, setDeleting] = useState<CaptureInfo | null>(null);
  const [reason, setReason] = useState('');
  const [opened, setOpened] = useState<string | null>(null);

  useEffect(() => setWhich(defaultWindow), [defaultWindow]);

  const reload = useCallback(async () => {
    try {
      setList(await scopeApi.kept(sid));
    } catch (e) {
      setFailure(failureOf(e, 'List the kept captures'));
    }
  }, [sid]);

  useEffect(() => {
    setList(null);
    void reload();
  }, [reload]);

  const blocked = rightBlocked('backup');
  const problem = titleProblem(title) ?? noteProblem(note);

  async function keep() {
    setTried(true);
    if (problem) return;
    setFailure(null);
    setBusy('keep');
    try {
      await scopeApi.keep(sid, { title: title.trim(), note, window: which, attach });
      setTitle('');
      setNote('');
      setAttach(false);
      setTried(false);
      await reload();
    } catch (e) {
      setFailure(failureOf(e, 'Keep the capture'));
    } finally {
      setBusy(null);
    }
  }

  async function act(what: string, label: string, job: () => Promise<unknown>) {
    setFailure(null);
    setBusy(what);
    try {
      await job();
    } catch (e) {
      setFailure(failureOf(e, label));
    } finally {
      setBusy(null);
    }
  }

  const open = (c: CaptureInfo) =>
    act(`open-${c.id}`, 'Open the kept capture', async () => {
      const full = await scopeApi.keptOne(c.id);
      onOpen(full.recording, c.title);
      setOpened(c.id);
    });
  const csv = (c: CaptureInfo) =>
    act(`csv-${c.id}`, 'Export the kept capture as CSV', async () => {
      const f = await scopeApi.keptCsv(c.id);
      saveBlob(f.blob, f.filename ?? `${c.id}.csv`);
    });
  const replace = (next: CaptureInfo) => setList((l) => (l ?? []).map((x) => (x.id === next.id ? next : x)));
  const setAttached = (c: CaptureInfo, on: boolean) => {
    // The box follows the click at once (a checkbox that waits for the server reads as
    // ignored) and goes back if the server refuses.
    replace({ ...c, attached: on });
    return act(`attach-${c.id}`, on ? 'Attach the capture to the report' : 'Detach the capture from the report', async () => {
      try {
        replace(await scopeApi.attach(c.id, on));
      } catch (e) {
        replace(c);
        throw e;
      }
    });
  };

  async function forget() {
    if (!deleting || reasonProblem(reason)) return;
    const c = deleting;
    await act(`delete-${c.id}`, 'Delete the kept capture', async () => {
      await scopeApi.forget(c.id, reason.trim());
      setDeleting(null);
      setReason('');
      await reload();
    });
  }

  const titleError = tried ? titleProblem(title) : null;
  const noteError = tried ? noteProblem(note) : null;

  return (
    <section className="card" data-testid="scope-kept">
      <h2>
        Kept captures of this drive
        <span className="h2-side small muted">in the store: every gateway and a restart see them</span>
      </h2>
      <form
        className="kept-form"
        onSubmit={(e) => {
          e.preventDefault();
          void keep();
        }}
        data-testid="scope-keep-form"
      >
        <label>
          Title
          <input
            type="text"
            value={title}
            maxLength={MAX_TITLE}
            onChange={(e) => setTitle(e.target.value)}
            aria-invalid={titleError ? true : undefined}
            aria-describedby={titleError ? 'scope-keep-title-error' : undefined}
            placeholder="e.g. velocity ripple at 300 rpm"
            data-testid="scope-keep-title"
          />
        </label>
        <label className="kept-note">
          Note
          <textarea value={note} maxLength={MAX_NOTE} rows={2} onChange={(e) => setNote(e.target.value)} data-testid="scope-keep-note" />
        </label>
        <label>
          What
          <select value={which} onChange={(e) => setWhich(e.target.value as 'capture' | 'buffer')} data-testid="scope-keep-window">
            <option value="capture">the captured window</option>
            <option value="buffer">the whole buffer</option>
          </select>
        </label>
        <label className="kept-check">
          <input type="checkbox" checked={attach} onChange={(e) => setAttach(e.target.checked)} data-testid="scope-keep-attach" />
          attach to the drive's report
        </label>
        <button
          type="submit"
          className="primary"
          disabled={busy !== null || blocked !== null || canKeep !== null}
          title={blocked ?? canKeep ?? 'keep it in the store with this title and note'}
          data-testid="scope-keep"
        >
          {busy === 'keep' ? 'Keeping…' : 'Keep capture'}
        </button>
      </form>
      {(titleError || noteError) && (
        <div className="failure small" role="alert" id="scope-keep-title-error" data-testid="scope-keep-problem">
          {titleError ?? noteError}
        </div>
      )}
      {failure && <FailureBox f={failure} testid="scope-kept-failure" />}
      {list === null ? (
        <div className="muted">Reading the kept captures…</div>
      ) : list.length === 0 ? (
        <div className="muted" data-testid="scope-kept-empty">
          No capture of this drive is kept yet.
        </div>
      ) : (
        <table className="grid kept-table" data-testid="scope-kept-list">
          <thead>
            <tr>
              <th>Title</th>
              <th>Kept</th>
              <th>Channels (unit)</th>
              <th className="num">Samples</th>
              <th>Sample period</th>
              <th>Report</th>
              <th />
            </tr>
          </thead>
          <tbody>
            {list.map((c) => (
              <tr key={c.id} data-testid="scope-kept-row" data-id={c.id} className={opened === c.id ? 'kept-open' : undefined}>
                <td>
                  <strong>{c.title}</strong>
                  {c.note && <div className="small muted kept-note-text">{c.note}</div>}
                </td>
                <td className="small">
                  {keptWhen(c)}
                  <div className="muted">
                    {c.by} · {c.window === 'capture' ? 'captured window' : 'buffer'} · {c.gateway}
                  </div>
                </td>
                <td className="small" title={c.channels.map((ch) => `${ch.name} ${ch.address}: ${unitText(ch)}`).join('\n')}>
                  {channelsText(c.channels)}
                </td>
                <td className="mono num">{c.samples}</td>
                <td className="small mono">{capturePeriod(c.channels)}</td>
                <td>
                  <label className="kept-check">
                    <input
                      type="checkbox"
                      checked={c.attached}
                      disabled={busy !== null || blocked !== null}
                      title={blocked ?? 'the drive\'s next commissioning reports show it'}
                      onChange={(e) => void setAttached(c, e.target.checked)}
                      data-testid="scope-kept-attach"
                    />
                    attached
                  </label>
                </td>
                <td className="kept-actions">
                  <button type="button" className="small-btn" disabled={busy !== null} onClick={() => void open(c)} data-testid="scope-kept-open">
                    Open
                  </button>
                  <button type="button" className="small-btn" disabled={busy !== null} onClick={() => void csv(c)} data-testid="scope-kept-csv">
                    CSV
                  </button>
                  <button
                    type="button"
                    className="small-btn"
                    disabled={busy !== null || blocked !== null}
                    title={blocked ?? undefined}
                    onClick={() => {
                      setReason('');
                      setDeleting(c);
                    }}
                    data-testid="scope-kept-delete"
                  >
                    Delete…
                  </button>
                </td>
              </tr>
            ))}
          </tbody>
        </table>
      )}
      {deleting && (
        <ConfirmDialog
          title={`Delete the kept capture "${deleting.title}"?`}
          confirmLabel="Delete"
          busy={busy !== null}
          onCancel={() => setDeleting(null)}
          onConfirm={() => void forget()}
          testid="scope-kept-delete-dialog"
        >
          <p>It goes from the store for every gateway; a report made with it keeps its copy. The audit log keeps who deleted it, when and why.</p>
          <label className="kept-reason">
            Reason
            <input type="text" value={reason} maxLength={2000} onChange={(e) => setReason(e.target.value)} data-testid="scope-kept-delete-reason" />
          </label>
          {reasonProblem(reason) && <div className="small muted">{reasonProblem(reason)}</div>}
        </ConfirmDialog>
      )}
    </section>
  );
}
