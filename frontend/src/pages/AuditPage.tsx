/**
 * Audit: who did what to which drive, when, from where, and whether it worked (IEC 62443-4-2
 * CR 2.8; docs/security.md "Audit log"). A table of the records, newest first, with filters
 * (category, user, drive, time range), the next page on demand, an export of the whole log
 * (JSON lines or CSV, with the hashes), and whether the hash chain still verifies
 * (GET /audit/verify): a record altered, removed or moved in the database shows here.
 */
import { useCallback, useEffect, useState } from 'react';
import { auditApi } from '../api/client';
import type { AuditCategory, AuditFilter, AuditRecord, AuditVerdict } from '../api/types';
import { saveBlob } from '../components/pdo/download';
import { FailureBox } from '../components/FailureBox';
import { detailsText, localTime, localToIso } from '../lib/audit';
import { type Failure, failureOf } from '../lib/codes';
import './audit.css';

const PAGE = 200;

const CATEGORIES: ReadonlyArray<[AuditCategory, string]> = [
  ['access_control', 'Access control'],
  ['request_error', 'Request errors'],
  ['control', 'Control'],
  ['motion', 'Motion'],
  ['write', 'Writes'],
  ['backup', 'Backup'],
  ['restore', 'Restore'],
  ['configuration', 'Configuration'],
  ['user_admin', 'User administration'],
];

interface Form {
  category: AuditCategory | '';
  user: string;
  drive: string;
  /** datetime-local values (the browser's local time). */
  since: string;
  until: string;
}

const EMPTY: Form = { category: '', user: '', drive: '', since: '', until: '' };

function toFilter(f: Form): AuditFilter {
  return {
    category: f.category || null,
    user: f.user.trim() || null,
    drive: f.drive.trim() || null,
    since: localToIso(f.since),
    until: localToIso(f.until),
    limit: PAGE,
  };
}

export function AuditPage() {
  const [form, setForm] = useState<Form>(EMPTY);
  const [applied, setApplied] = useState<AuditFilter>(toFilter(EMPTY));
  const [records, setRecords] = useState<AuditRecord[] | null>(null);
  const [more, setMore] = useState(false);
  const [verdict, setVerdict] = useState<AuditVerdict | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [busy, setBusy] = useState<'load' | 'more' | 'jsonl' | 'csv' | null>(null);

  const load = useCallback(async (filter: AuditFilter) => {
    setBusy('load');
    try {
      const [rows, v] = await Promise.all([auditApi.list(filter), auditApi.verify()]);
      setRecords(rows);
      setMore(rows.length === PAGE);
      setVerdict(v);
      setFailure(null);
    } catch (e) {
      setFailure(failureOf(e, 'Load the audit log'));
    } finally {
      setBusy(null);
    }
  }, []);

  useEffect(() => {
    void load(applied);
  }, [load, applied]);

  const loadMore = async () => {
    if (!records || records.length === 0) return;
    setBusy('more');
    try {
      const rows = await auditApi.list({ ...applied, before: records[records.length - 1]!.seq });
      setRecords([...records, ...rows]);
      setMore(rows.length === PAGE);
    } catch (e) {
      setFailure(failureOf(e, 'Load older audit records'));
    } finally {
      setBusy(null);
    }
  };

  const exportAs = async (format: 'jsonl' | 'csv') => {
    setBusy(format);
    try {
      const file = await auditApi.export(format, applied.since);
      saveBlob(file.blob, file.filename ?? `servodesk-audit.${format}`);
    } catch (e) {
      setFailure(failureOf(e, `Export the audit log as ${format.toUpperCase()}`));
    } finally {
      setBusy(null);
    }
  };

  const set = (k: keyof Form) => (e: { target: { value: string } }) => setForm({ ...form, [k]: e.target.value });
  const apply = () => setApplied(toFilter(form));
  const clear = () => {
    setForm(EMPTY);
    setApplied(toFilter(EMPTY));
  };

  return (
    <div className="audit-page">
      <section className="card">
        <h2>
          Audit log
          <span className="h2-side">
            {verdict && verdict.ok && (
              <span className="audit-chain audit-chain-ok" data-testid="audit-chain" data-ok="true" title={`head ${verdict.head}`}>
                ✓ chain verified · {verdict.records} records
              </span>
            )}
            {verdict && !verdict.ok && (
              <span className="audit-chain audit-chain-bad" data-testid="audit-chain" data-ok="false">
                ✗ chain broken at record {verdict.broken}: {verdict.problem}
              </span>
            )}
            <button type="button" className="small-btn" onClick={() => void exportAs('jsonl')} disabled={busy !== null} data-testid="audit-export-jsonl">
              {busy === 'jsonl' ? 'Exporting…' : 'Export JSONL'}
            </button>{' '}
            <button type="button" className="small-btn" onClick={() => void exportAs('csv')} disabled={busy !== null} data-testid="audit-export-csv">
              {busy === 'csv' ? 'Exporting…' : 'Export CSV'}
            </button>
          </span>
        </h2>
        <form
          className="audit-filters"
          onSubmit={(e) => {
            e.preventDefault();
            apply();
          }}
        >
          <label>
            Category
            <select value={form.category} onChange={set('category')} data-testid="audit-category">
              <option value="">all</option>
              {CATEGORIES.map(([id, label]) => (
                <option key={id} value={id}>
                  {label}
                </option>
              ))}
            </select>
          </label>
          <label>
            User
            <input value={form.user} onChange={set('user')} placeholder="any" maxLength={200} data-testid="audit-user" />
          </label>
          <label>
            Drive
            <input value={form.drive} onChange={set('drive')} placeholder="any (session id)" maxLength={200} data-testid="audit-drive" />
          </label>
          <label>
            From
            <input type="datetime-local" step={1} value={form.since} onChange={set('since')} data-testid="audit-since" />
          </label>
          <label>
            To
            <input type="datetime-local" step={1} value={form.until} onChange={set('until')} data-testid="audit-until" />
          </label>
          <div className="audit-filter-actions">
            <button type="submit" disabled={busy !== null} data-testid="audit-apply">
              {busy === 'load' ? 'Loading…' : 'Apply'}
            </button>{' '}
            <button type="button" onClick={clear} disabled={busy !== null}>
              Clear
            </button>
          </div>
        </form>
        <div className="muted small">Times in this browser's time zone; the log and its exports keep UTC.</div>
      </section>
      {failure && <FailureBox f={failure} testid="audit-page-failure" />}
      {records && records.length === 0 && <div className="muted" data-testid="audit-empty">No audit records match.</div>}
      {records && records.length > 0 && (
        <section className="card">
          <div className="bk-table-wrap">
            <table className="grid audit-table" data-testid="audit-records">
              <thead>
                <tr>
                  <th className="num">#</th>
                  <th>Time</th>
                  <th>User</th>
                  <th>Source</th>
                  <th>Category</th>
                  <th>Event</th>
                  <th>Drive</th>
                  <th>Result</th>
                  <th>Message</th>
                  <th>Details</th>
                </tr>
              </thead>
              <tbody>
                {records.map((r) => (
                  <tr key={r.seq} data-testid="audit-record" data-event={r.event} data-result={r.result}>
                    <td className="mono num small">{r.seq}</td>
                    <td className="mono nowrap" title={r.time}>
                      {localTime(r.time)}
                    </td>
                    <td>{r.user}</td>
                    <td className="mono small">{r.address || <span className="muted">—</span>}</td>
                    <td className="small">{r.category}</td>
                    <td className="mono small">{r.event}</td>
                    <td className="mono small nowrap">{r.drive ?? <span className="muted">—</span>}</td>
                    <td>
                      <span className={r.result === 'success' ? 'ok-mark' : 'bad'}>{r.result}</span>
                    </td>
                    <td className="small">{r.message}</td>
                    <td className="mono small audit-details" title={JSON.stringify(r.details, null, 2)}>
                      {detailsText(r.details)}
                    </td>
                  </tr>
                ))}
              </tbody>
            </table>
          </div>
          {more && (
            <button type="button" className="small-btn" onClick={() => void loadMore()} disabled={busy !== null} data-testid="audit-more">
              {busy === 'more' ? 'Loading…' : 'Older records'}
            </button>
          )}
        </section>
      )}
    </div>
  );
}
