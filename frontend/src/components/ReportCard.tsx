/**
 * The drive's commissioning report (docs/report.md): made on request from what the drive and
 * the store hold now, opened in a new tab; its PDF printed by the server. The id and hash shown
 * here are the ones printed in the report, which `servodesk report verify` checks.
 */
import { useEffect, useState } from 'react';
import { type ReportInfo, openReport, reportApi } from '../api/report';
import { scopeApi } from '../api/scope';
import { notifyError } from '../state/notify';
import { saveBlob } from './pdo/download';

export function ReportCard({ sid }: { sid: string }) {
  const [busy, setBusy] = useState<'html' | 'pdf' | null>(null);
  const [made, setMade] = useState<ReportInfo | null>(null);
  // The kept scope captures the report will show (attached on the Scope page; issue 49).
  const [attached, setAttached] = useState<number | null>(null);

  useEffect(() => {
    let live = true;
    scopeApi.kept(sid).then(
      (list) => live && setAttached(list.filter((c) => c.attached).length),
      () => live && setAttached(null),
    );
    return () => {
      live = false;
    };
  }, [sid, made]);

  const make = async () => {
    setBusy('html');
    try {
      setMade(await openReport(sid));
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  };

  const pdf = async (info: ReportInfo) => {
    setBusy('pdf');
    try {
      const f = await reportApi.pdf(info.id);
      saveBlob(f.blob, f.filename ?? `${info.id}.pdf`);
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  };

  return (
    <section className="card" data-testid="report-card">
      <h2>
        Commissioning report <span className="h2-side muted">HTML, PDF</span>
      </h2>
      <p className="muted">
        Identity, parameters, PDO layout, limits, homing, tuning, attached scope captures, alarms and the audit extract, read now; kept in the store with its
        content hash.
      </p>
      {attached !== null && (
        <p className="small" data-testid="report-captures">
          {attached === 0 ? 'No scope capture attached' : `${attached} scope capture${attached === 1 ? '' : 's'} attached`} (
          <a href={`#/scope/${sid}`}>Scope page, kept captures</a>).
        </p>
      )}
      <div className="command-buttons">
        <button type="button" data-testid="report-make" disabled={busy !== null} onClick={() => void make()}>
          {busy === 'html' ? 'Commissioning report…' : 'Commissioning report'}
        </button>
        {made && (
          <button type="button" className="small-btn" data-testid="report-pdf" disabled={busy !== null} onClick={() => void pdf(made)}>
            {busy === 'pdf' ? 'PDF…' : 'PDF'}
          </button>
        )}
      </div>
      {made && (
        <p data-testid="report-made">
          Report <span className="mono">{made.id}</span>, SHA-256 <span className="mono" title={made.sha256}>{made.sha256.slice(0, 16)}…</span>
        </p>
      )}
    </section>
  );
}
