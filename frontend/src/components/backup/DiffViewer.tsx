/**
 * The diff viewer (POST /compare): A and B are each the live drive, the profile's defaults or
 * a backup. Only differences are shown unless "show all" is on; rows are grouped as the
 * profile groups its objects, and each side shows its value in engineering units with the
 * unit and the raw bytes in hex, labelled. Equal sources say so plainly: "No differences".
 */
import { Fragment, useCallback, useEffect, useRef, useState } from 'react';
import { backupApi } from '../../api/client';
import type { BackupInfo, Comparison, ErrorInfo, GroupInfo } from '../../api/types';
import { type SourceKey, diffCounts, groupDifferences, isDifference, isEqual, kindLabel, sideCell, sourceFromKey, sourceLabel } from '../../lib/backupDiff';
import { backupTitle } from '../../lib/backupHistory';
import { type Failure, failureOf } from '../../lib/codes';
import { FailureBox } from '../FailureBox';
import { UnreadableList, objectsText } from './UnreadableList';

/** A request from elsewhere on the page to compare two sources now. */
export interface CompareAsk {
  a: SourceKey;
  b: SourceKey;
  nonce: number;
}

interface Shown {
  c: Comparison;
  a: SourceKey;
  b: SourceKey;
  all: boolean;
}

function SourceSelect({ value, onChange, backups, testid, side }: { value: SourceKey; onChange: (k: SourceKey) => void; backups: readonly BackupInfo[]; testid: string; side: 'A' | 'B' }) {
  const known = value === 'drive' || value === 'defaults' || backups.some((b) => `backup:${b.id}` === value);
  return (
    <label>
      <span>
        <span className={`side-tag side-${side.toLowerCase()}`}>{side}</span>
      </span>
      <select data-testid={testid} value={value} onChange={(e) => onChange(e.target.value)}>
        <option value="drive">Live drive</option>
        <option value="defaults">Profile defaults</option>
        {backups.length > 0 && (
          <optgroup label="Backups">
            {backups.map((b) => (
              <option key={b.id} value={`backup:${b.id}`}>
                {backupTitle(b)}
              </option>
            ))}
          </optgroup>
        )}
        {!known && <option value={value}>{sourceLabel(value, backups)}</option>}
      </select>
    </label>
  );
}

export function DiffViewer({
  sid,
  profileId,
  backups,
  groups,
  errors,
  ask,
  refreshNonce,
}: {
  sid: string;
  profileId: string | null;
  backups: readonly BackupInfo[];
  groups: readonly GroupInfo[];
  errors: readonly ErrorInfo[];
  ask: CompareAsk | null;
  /** Bumped after the drive changed (a restore): a shown comparison is run again. */
  refreshNonce: number;
}) {
  const [a, setA] = useState<SourceKey>('drive');
  const [b, setB] = useState<SourceKey>(backups[0] ? `backup:${backups[0].id}` : 'defaults');
  const [showAll, setShowAll] = useState(false);
  const [busy, setBusy] = useState(false);
  const [shown, setShown] = useState<Shown | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const touchedB = useRef(false);
  const seq = useRef(0);

  // Until the person chooses B, B follows the newest backup (the usual question: "what
  // changed since the last backup?").
  useEffect(() => {
    if (!touchedB.current && backups[0]) setB(`backup:${backups[0].id}`);
  }, [backups]);

  const run = useCallback(
    async (ka: SourceKey, kb: SourceKey, all: boolean) => {
      if (!profileId) return;
      const sa = sourceFromKey(ka, sid, profileId);
      const sb = sourceFromKey(kb, sid, profileId);
      if (!sa || !sb) return;
      const my = ++seq.current;
      setBusy(true);
      setFailure(null);
      try {
        const c = await backupApi.compare({ a: sa, b: sb, all });
        if (my === seq.current) setShown({ c, a: ka, b: kb, all });
      } catch (e) {
        if (my === seq.current) {
          setShown(null);
          setFailure(failureOf(e, 'Compare', errors));
        }
      } finally {
        if (my === seq.current) setBusy(false);
      }
    },
    [sid, profileId, errors],
  );

  useEffect(() => {
    if (!ask) return;
    setA(ask.a);
    setB(ask.b);
    touchedB.current = true;
    void run(ask.a, ask.b, showAll);
    // Only a new ask runs a comparison; showAll is read as it is then.
  }, [ask]);

  const lastShown = useRef<Shown | null>(null);
  lastShown.current = shown;
  useEffect(() => {
    const s = lastShown.current;
    if (refreshNonce > 0 && s) void run(s.a, s.b, s.all);
  }, [refreshNonce, run]);

  function toggleAll(next: boolean) {
    setShowAll(next);
    // Equal entries come from the server only when asked for ("all": true).
    if (shown && next && !shown.all) void run(shown.a, shown.b, true);
  }

  const c = shown?.c ?? null;
  const counts = c ? diffCounts(c) : null;
  const equal = c ? isEqual(c) : false;
  const grouped = c ? groupDifferences(c, groups, showAll) : [];
  const equalListed = c ? c.differences.filter((d) => !isDifference(d)).length : 0;
  const notCompared = c ? new Set([...c.a_unreadable, ...c.b_unreadable].map((u) => u.address)).size : 0;

  return (
    <section className="card" data-testid="diff-viewer">
      <h2>Compare</h2>
      <div className="diff-controls">
        <SourceSelect side="A" value={a} onChange={setA} backups={backups} testid="diff-a" />
        <button
          type="button"
          className="small-btn"
          title="Swap A and B"
          aria-label="Swap A and B"
          onClick={() => {
            setA(b);
            setB(a);
            touchedB.current = true;
          }}
        >
          ⇄
        </button>
        <SourceSelect
          side="B"
          value={b}
          onChange={(k) => {
            touchedB.current = true;
            setB(k);
          }}
          backups={backups}
          testid="diff-b"
        />
        <button type="button" className="primary" data-testid="diff-run" onClick={() => void run(a, b, showAll)} disabled={busy || !profileId || a === b}>
          {busy ? 'Comparing…' : 'Compare'}
        </button>
        <label className="check">
          <input type="checkbox" data-testid="diff-show-all" checked={showAll} onChange={(e) => toggleAll(e.target.checked)} /> Show all (also equal entries)
        </label>
      </div>
      {a === b && <div className="muted small">A and B are the same source; choose two different ones.</div>}
      {failure && <FailureBox f={failure} testid="diff-failure" />}
      {c && shown && counts && (
        <div data-testid="diff-result" data-equal={equal ? 'true' : 'false'}>
          <div className="diff-summary">
            <span>
              <span className="side-tag side-a">A</span>
              <span data-testid="diff-a-label">{c.a || sourceLabel(shown.a, backups)}</span>
            </span>
            <span>
              <span className="side-tag side-b">B</span>
              <span data-testid="diff-b-label">{c.b || sourceLabel(shown.b, backups)}</span>
            </span>
            <span className="muted" data-testid="diff-counts">
              {counts.changed} changed · {counts.onlyA} only in A · {counts.onlyB} only in B · {counts.same} equal
              {notCompared > 0 && <span data-testid="diff-not-compared"> · {notCompared} not compared (unreadable)</span>}
            </span>
            {busy && <span className="muted small">updating…</span>}
          </div>
          {equal && (
            <div className="diff-equal" data-testid="diff-equal" role="status">
              No differences{' '}
              <span className="muted">
                — all {counts.same} compared entries are equal
                {notCompared > 0 ? `; ${objectsText(notCompared)} could not be compared (unreadable, below)` : ''}.
              </span>
            </div>
          )}
          <UnreadableList
            items={c.a_unreadable}
            headline={`Not compared: ${objectsText(c.a_unreadable.length)} unreadable in A (${c.a || sourceLabel(shown.a, backups)}).`}
            testid="diff-a-unreadable"
          />
          <UnreadableList
            items={c.b_unreadable}
            headline={`Not compared: ${objectsText(c.b_unreadable.length)} unreadable in B (${c.b || sourceLabel(shown.b, backups)}).`}
            testid="diff-b-unreadable"
          />
          {showAll && shown.all && equalListed === 0 && counts.same > 0 && (
            <div className="muted small" style={{ margin: '6px 0' }}>
              The server listed no equal entries; {counts.same} entries are equal.
            </div>
          )}
          {grouped.length > 0 && (
            <div className="bk-table-wrap tall">
              <table className="grid bk-table diff-table" data-testid="diff-table">
                <thead>
                  <tr>
                    <th>Kind</th>
                    <th>Address</th>
                    <th>Name</th>
                    <th className="side-a-col num">
                      <span className="side-tag side-a">A</span>value (eng. unit)
                    </th>
                    <th className="side-a-col">
                      <span className="side-tag side-a">A</span>raw hex (bus order)
                    </th>
                    <th className="side-b-col num">
                      <span className="side-tag side-b">B</span>value (eng. unit)
                    </th>
                    <th className="side-b-col">
                      <span className="side-tag side-b">B</span>raw hex (bus order)
                    </th>
                  </tr>
                </thead>
                <tbody>
                  {grouped.map((g) => (
                    <Fragment key={g.id || '-'}>
                      <tr className="group-row" data-testid="diff-group">
                        <td colSpan={7}>
                          {g.name} <span className="muted">({g.differences} difference{g.differences === 1 ? '' : 's'})</span>
                        </td>
                      </tr>
                      {g.rows.map((d) => {
                        const ca = sideCell(d, 'a');
                        const cb = sideCell(d, 'b');
                        const kind = isDifference(d) ? d.kind : 'equal';
                        return (
                          <tr key={d.address} className={`row-${kind}`} data-testid="diff-row" data-address={d.address} data-kind={kind}>
                            <td>
                              <span className={`kind kind-${kind}`}>{kindLabel(kind)}</span>
                            </td>
                            <td className="mono">{d.address}</td>
                            <td>{d.name ?? <span className="muted">—</span>}</td>
                            <td className={`mono num side-a-col${ca.absent ? ' absent' : ''}`} data-testid="diff-a-value">
                              {ca.absent ? 'not in A' : ca.value}
                            </td>
                            <td className={`mono raw side-a-col${ca.absent ? ' absent' : ''}`} data-testid="diff-a-raw">
                              {ca.absent ? '' : ca.raw}
                            </td>
                            <td className={`mono num side-b-col${cb.absent ? ' absent' : ''}`} data-testid="diff-b-value">
                              {cb.absent ? 'not in B' : cb.value}
                            </td>
                            <td className={`mono raw side-b-col${cb.absent ? ' absent' : ''}`} data-testid="diff-b-raw">
                              {cb.absent ? '' : cb.raw}
                            </td>
                          </tr>
                        );
                      })}
                    </Fragment>
                  ))}
                </tbody>
              </table>
            </div>
          )}
        </div>
      )}
      {!c && !failure && <div className="muted">Choose A and B and press Compare.</div>}
    </section>
  );
}
