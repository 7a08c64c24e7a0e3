/**
 * The audit log of this session (GET /audit/writes?session=): who (the client id: a browser tab or
 * the CLI) wrote what, old and new value. DESIGN.md "Rules that hold everywhere": every write
 * is logged (who, what, old, new).
 */
import { useCallback, useEffect, useState } from 'react';
import { backupApi } from '../../api/client';
import type { AuditEntry, ErrorInfo, ObjectScalar } from '../../api/types';
import { tabClientId } from '../../lib/backupClientId';
import { formatTime } from '../../lib/backupHistory';
import { type Failure, failureOf } from '../../lib/codes';
import { formatRawBytes, toDec } from '../../lib/format';
import { FailureBox } from '../FailureBox';

const LIMIT = 100;

function valueText(v: ObjectScalar | null, raw: string | null): string {
  if (v === null || v === undefined) return raw ? formatRawBytes(raw) : '—';
  if (typeof v === 'number') return toDec(v);
  if (typeof v === 'boolean') return v ? '1' : '0';
  return v;
}

export function AuditLog({ sid, errors, refreshNonce }: { sid: string; errors: readonly ErrorInfo[]; refreshNonce: number }) {
  const [entries, setEntries] = useState<AuditEntry[] | null>(null);
  const [loading, setLoading] = useState(false);
  const [failure, setFailure] = useState<Failure | null>(null);
  const me = tabClientId();

  const load = useCallback(async () => {
    setLoading(true);
    try {
      setEntries(await backupApi.audit(sid, LIMIT));
      setFailure(null);
    } catch (e) {
      setFailure(failureOf(e, 'Load the audit log', errors));
    } finally {
      setLoading(false);
    }
  }, [sid, errors]);

  useEffect(() => {
    void load();
  }, [load, refreshNonce]);

  return (
    <section className="card" data-testid="audit-log">
      <h2>
        Audit log
        <span className="h2-side">
          <span className="muted small">this session, newest first · this tab is </span>
          <span className="mono small">{me}</span>{' '}
          <button type="button" className="small-btn" onClick={() => void load()} disabled={loading} data-testid="audit-refresh">
            {loading ? 'Loading…' : 'Refresh'}
          </button>
        </span>
      </h2>
      {failure && <FailureBox f={failure} testid="audit-failure" />}
      {entries && entries.length === 0 && <div className="muted">No writes recorded for this session yet.</div>}
      {entries && entries.length > 0 && (
        <div className="bk-table-wrap">
          <table className="grid bk-table" data-testid="audit-table">
            <thead>
              <tr>
                <th>Time</th>
                <th>Client</th>
                <th>Address</th>
                <th>Name</th>
                <th className="num">Old</th>
                <th />
                <th className="num">New</th>
                <th>Raw hex old → new</th>
              </tr>
            </thead>
            <tbody>
              {entries.map((e, i) => (
                <tr key={`${String(e.time)}-${e.address}-${i}`} data-testid="audit-row" data-address={e.address}>
                  <td className="mono nowrap">{formatTime(e.time)}</td>
                  <td className="mono small">
                    {e.client}
                    {e.client === me && <span className="audit-self">this tab</span>}
                  </td>
                  <td className="mono">{e.address}</td>
                  <td>{e.name ?? <span className="muted">—</span>}</td>
                  <td className="mono num">{valueText(e.old_value, e.old_raw_hex)}</td>
                  <td className="arrow">→</td>
                  <td className="mono num">{valueText(e.new_value, e.new_raw_hex)}</td>
                  <td className="mono small muted">
                    {formatRawBytes(e.old_raw_hex)} → {formatRawBytes(e.new_raw_hex)}
                  </td>
                </tr>
              ))}
            </tbody>
          </table>
        </div>
      )}
    </section>
  );
}
