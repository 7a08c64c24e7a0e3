/**
 * The fleet (issue 49): every drive the store knows, from every gateway that shares it — its
 * plant tag, the gateway that connected it last (a link to the drive there), family,
 * firmware, last backup, approved ("golden") backup with who approved it and why, drift state
 * (unknown / in step / drifted with how many parameters and when), the last tuning kept in the
 * store (when, how it ended, mode), open alarms when known.
 * A text search over tag, key, serial and family, a drift-state filter, and pages of
 * {@link PAGE} drives (the query runs on the server: a plant has 10 000 drives). A drifted
 * drive's row opens the differing parameters of its last check (GET /fleet/drift).
 *
 * Tags and approvals are set through the API (PUT /fleet/tag, PUT /fleet/approved; docs/api.md);
 * an approval is cleared here, with a reason (DELETE /fleet/approved).
 */
import { Fragment, useCallback, useEffect, useState } from 'react';
import { type DriftResult, type DriftState, type FleetDrive, type FleetFilter, type FleetPage as Page, fleetApi } from '../api/fleet';
import { FailureBox } from '../components/FailureBox';
import { localTime } from '../lib/audit';
import { formatEngineering } from '../lib/format';
import { type Failure, failureOf } from '../lib/codes';
import './fleet.css';

const PAGE = 100;

const DRIFT: ReadonlyArray<[DriftState, string]> = [
  ['unknown', 'unknown'],
  ['in_step', 'in step'],
  ['drifted', 'drifted'],
];

function when(iso: string | null | undefined): string {
  return iso ? localTime(iso) : '—';
}

function DriftCell({ d }: { d: FleetDrive }) {
  const { state, count, time } = d.drift;
  if (state === 'drifted') {
    return (
      <span className="fleet-drift fleet-drifted" title={`checked ${when(time)}`}>
        drifted · {count} {count === 1 ? 'parameter' : 'parameters'}
      </span>
    );
  }
  if (state === 'in_step') {
    return (
      <span className="fleet-drift fleet-in-step" title={`checked ${when(time)}`}>
        in step
      </span>
    );
  }
  return <span className="muted">{d.approved ? 'not checked' : 'unknown'}</span>;
}

/** A raw value in drive units (its hex in the tooltip), the engineering value below. */
function ValueCell(p: { present: boolean; value: number | string | boolean | null | undefined; rawHex: string | null | undefined; rawUnit: string | null | undefined; eng: number | null | undefined; unit: string | null | undefined }) {
  if (!p.present) return <td className="num muted">—</td>;
  return (
    <td className="num" title={p.rawHex ? `raw 0x${p.rawHex}` : undefined}>
      <span className="mono">{String(p.value ?? '')}</span> <span className="unit">{p.rawUnit ?? ''}</span>
      {p.eng !== null && p.eng !== undefined && <div className="mono muted small">{formatEngineering(p.eng, p.unit)}</div>}
    </td>
  );
}

function Differences({ drive }: { drive: FleetDrive }) {
  const [result, setResult] = useState<DriftResult | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  useEffect(() => {
    fleetApi
      .drift(drive.drive_key, 1)
      .then((rows) => setResult(rows[0] ?? null))
      .catch((e: unknown) => setFailure(failureOf(e, 'Load the drift result')));
  }, [drive.drive_key]);
  if (failure) return <FailureBox f={failure} />;
  if (!result) return <span className="muted">Loading…</span>;
  return (
    <div data-testid="fleet-differences">
      <div className="muted small">
        {when(result.time)} on {result.gateway} ({result.session}) against approved backup <span className="mono">{result.backup}</span>
      </div>
      <table className="grid fleet-diff-table">
        <thead>
          <tr>
            <th>Object</th>
            <th>Name</th>
            <th className="num">Approved</th>
            <th className="num">Drive</th>
          </tr>
        </thead>
        <tbody>
          {result.differences.map((x) => (
            <tr key={x.address} data-testid="fleet-difference" data-address={x.address}>
              <td className="mono">{x.address}</td>
              <td>{x.name}</td>
              <ValueCell present={x.kind !== 'only_b'} value={x.approved_value} rawHex={x.approved_raw_hex} rawUnit={x.raw_unit} eng={x.approved_engineering} unit={x.unit} />
              <ValueCell present={x.kind !== 'only_a'} value={x.drive_value} rawHex={x.drive_raw_hex} rawUnit={x.raw_unit} eng={x.drive_engineering} unit={x.unit} />
            </tr>
          ))}
        </tbody>
      </table>
    </div>
  );
}

/** Clearing an approval (DELETE /fleet/approved): asked to confirm, with the reason the audit
 * log keeps; the drive's drift state is unknown afterwards. */
function ClearApproval({ d, cleared }: { d: FleetDrive; cleared: () => void }) {
  const [asking, setAsking] = useState(false);
  const [reason, setReason] = useState('');
  const [failure, setFailure] = useState<Failure | null>(null);
  const [busy, setBusy] = useState(false);
  if (!asking) {
    return (
      <button type="button" className="small-btn" onClick={() => setAsking(true)} data-testid="fleet-clear-approval">
        Clear…
      </button>
    );
  }
  const submit = async () => {
    setBusy(true);
    try {
      await fleetApi.clearApproval(d.drive_key, reason.trim());
      setAsking(false);
      cleared();
    } catch (e) {
      setFailure(failureOf(e, 'Clear the approval'));
    } finally {
      setBusy(false);
    }
  };
  return (
    <form
      className="fleet-clear"
      onSubmit={(e) => {
        e.preventDefault();
        void submit();
      }}
    >
      <div className="small">Clear the approved backup? Drift checks stop until another is approved.</div>
      <input value={reason} onChange={(e) => setReason(e.target.value)} placeholder="reason (required)" maxLength={2000} aria-label="Reason" data-testid="fleet-clear-reason" />{' '}
      <button type="submit" className="small-btn" disabled={busy || !reason.trim()} data-testid="fleet-clear-confirm">
        Clear approval
      </button>{' '}
      <button type="button" className="small-btn" onClick={() => setAsking(false)} disabled={busy}>
        Cancel
      </button>
      {failure && <FailureBox f={failure} />}
    </form>
  );
}

function Row({ d, open, toggle, reload }: { d: FleetDrive; open: boolean; toggle: () => void; reload: () => void }) {
  const t = d.last_tuning;
  return (
    <Fragment>
      <tr data-testid="fleet-row" data-drive={d.drive_key} data-drift={d.drift.state}>
        <td className="mono" data-testid="fleet-tag">
          {d.plant_tag ?? <span className="muted">—</span>}
        </td>
        <td className="mono small" title={d.serial ? `serial ${d.serial}` : undefined}>
          {d.drive_key}
        </td>
        <td className="small">{d.profile_id}</td>
        <td className="mono small">{d.firmware ?? '—'}</td>
        <td className="small">
          {d.link ? (
            <a href={d.link} data-testid="fleet-link" title={`open ${d.session ?? 'the drive'} on ${d.gateway}`}>
              {d.gateway}
            </a>
          ) : (
            <span className="muted">{d.gateway ?? '—'}</span>
          )}
          {d.seen && <div className="muted small">seen {when(d.seen)}</div>}
        </td>
        <td className="mono small nowrap">{d.last_backup_time ? when(d.last_backup_time) : <span className="muted">none</span>}</td>
        <td className="small" data-testid="fleet-approved">
          {d.approved ? (
            <span title={`${d.approved.reason ?? ''}\napproved by ${d.approved.by ?? '?'} ${when(d.approved.at)}`}>
              <span className="mono">{d.approved.backup}</span>
              <div className="muted small">
                {d.approved.by} · {d.approved.reason}
              </div>
              <ClearApproval d={d} cleared={reload} />
            </span>
          ) : (
            <span className="muted">none</span>
          )}
        </td>
        <td data-testid="fleet-drift">
          {d.drift.state === 'drifted' ? (
            <button type="button" className="fleet-toggle" onClick={toggle} aria-expanded={open} data-testid="fleet-drift-toggle">
              <DriftCell d={d} />
            </button>
          ) : (
            <DriftCell d={d} />
          )}
        </td>
        <td className="small nowrap" data-testid="fleet-last-tuning" title={t ? `stored tuning ${t.id}` : undefined}>
          {t ? (
            <>
              <span className="mono">{when(t.time)}</span>
              <div className={t.status === 'done' ? 'muted small' : 'bad small'}>
                {t.status} · {t.mode}
              </div>
            </>
          ) : (
            <span className="muted">none</span>
          )}
        </td>
        <td className={d.alarms ? 'bad num' : 'muted num'}>{d.alarms ?? '—'}</td>
      </tr>
      {open && (
        <tr className="fleet-detail">
          <td colSpan={10}>
            <Differences drive={d} />
          </td>
        </tr>
      )}
    </Fragment>
  );
}

export function FleetPage() {
  const [text, setText] = useState('');
  const [filter, setFilter] = useState<FleetFilter>({ q: '', drift: null, offset: 0, limit: PAGE });
  const [page, setPage] = useState<Page | null>(null);
  const [open, setOpen] = useState<string | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [busy, setBusy] = useState(false);

  const load = useCallback(async (f: FleetFilter) => {
    setBusy(true);
    try {
      setPage(await fleetApi.list(f));
      setFailure(null);
    } catch (e) {
      setFailure(failureOf(e, 'Load the fleet'));
    } finally {
      setBusy(false);
    }
  }, []);

  useEffect(() => {
    void load(filter);
  }, [load, filter]);

  const total = page?.total ?? 0;
  const first = total === 0 ? 0 : filter.offset + 1;
  const last = Math.min(filter.offset + PAGE, total);

  return (
    <div className="fleet-page">
      <section className="card">
        <h2>
          Fleet
          <span className="h2-side muted small" data-testid="fleet-count">
            {page ? `${first}–${last} of ${total} drives` : ''}
          </span>
        </h2>
        <form
          className="fleet-filters"
          onSubmit={(e) => {
            e.preventDefault();
            setFilter({ ...filter, q: text.trim(), offset: 0 });
          }}
        >
          <label>
            Search
            <input value={text} onChange={(e) => setText(e.target.value)} placeholder="tag, serial, family" maxLength={200} data-testid="fleet-search" />
          </label>
          <label>
            Drift
            <select
              value={filter.drift ?? ''}
              onChange={(e) => setFilter({ ...filter, drift: (e.target.value || null) as DriftState | null, offset: 0 })}
              data-testid="fleet-drift-filter"
            >
              <option value="">any</option>
              {DRIFT.map(([id, label]) => (
                <option key={id} value={id}>
                  {label}
                </option>
              ))}
            </select>
          </label>
          <div className="fleet-filter-actions">
            <button type="submit" disabled={busy} data-testid="fleet-apply">
              {busy ? 'Loading…' : 'Search'}
            </button>{' '}
            <button type="button" onClick={() => void load(filter)} disabled={busy}>
              Refresh
            </button>
          </div>
        </form>
        <div className="muted small">Every drive the store knows, from every gateway. Set plant tags and approve backups through the API (PUT /api/v1/fleet/tag, /fleet/approved).</div>
      </section>
      {failure && <FailureBox f={failure} testid="fleet-failure" />}
      {page && page.drives.length === 0 && (
        <div className="muted" data-testid="fleet-empty">
          No drives match.
        </div>
      )}
      {page && page.drives.length > 0 && (
        <section className="card">
          <div className="bk-table-wrap">
            <table className="grid fleet-table" data-testid="fleet-table">
              <thead>
                <tr>
                  <th>Plant tag</th>
                  <th>Drive</th>
                  <th>Family</th>
                  <th>Firmware</th>
                  <th>Gateway</th>
                  <th>Last backup</th>
                  <th>Approved backup</th>
                  <th>Drift</th>
                  <th>Last tuning</th>
                  <th className="num">Alarms</th>
                </tr>
              </thead>
              <tbody>
                {page.drives.map((d) => (
                  <Row key={d.drive_key} d={d} open={open === d.drive_key} toggle={() => setOpen(open === d.drive_key ? null : d.drive_key)} reload={() => void load(filter)} />
                ))}
              </tbody>
            </table>
          </div>
          <div className="fleet-pager">
            <button type="button" className="small-btn" disabled={busy || filter.offset === 0} onClick={() => setFilter({ ...filter, offset: Math.max(0, filter.offset - PAGE) })} data-testid="fleet-prev">
              Previous
            </button>{' '}
            <button type="button" className="small-btn" disabled={busy || last >= total} onClick={() => setFilter({ ...filter, offset: filter.offset + PAGE })} data-testid="fleet-next">
              Next
            </button>
          </div>
        </section>
      )}
    </div>
  );
}
