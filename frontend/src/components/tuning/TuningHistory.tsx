/**
 * The drive's tuning history (issue 49; docs/ui.md "Tuning"): every tuning of this drive kept
 * in the store, from every session and gateway, newest first: when it ended, who ran it, the
 * kind and response level, how it ended, whether its gains stayed, the margins and the
 * bandwidth. Open shows one result's margins, Bode plot, step responses and gains as the
 * Result step shows the session's last one. `refresh` changes when a tuning ended here.
 */
import { useCallback, useEffect, useState } from 'react';
import { type StoredTuningResult, type TuningRecord, type TuningResult, tuningApi } from '../../api/tuning';
import { type Failure, failureOf } from '../../lib/codes';
import { FailureBox } from '../FailureBox';
import { GainTable } from './GainTable';
import { BodePlot, StepPlot } from './TuningPlots';
import { MARGINS_FOR, bandwidthText, durationText, endedText, marginsText, statusText } from './history';
import { gainLines, withUnit } from './tuningModel';

type Margins = TuningResult['margins'];

export function TuningHistory({ sid, refresh }: { sid: string; refresh: string }) {
  const [rows, setRows] = useState<TuningRecord[] | null>(null);
  const [margins, setMargins] = useState<Map<string, Margins>>(new Map());
  const [open, setOpen] = useState<StoredTuningResult | null>(null);
  const [busy, setBusy] = useState<string | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);

  const load = useCallback(async () => {
    setFailure(null);
    try {
      const list = await tuningApi.history(sid);
      setRows(list);
      // The list has no margins: the newest results are read for them, one after another
      // (a store on a slow network is not asked for twenty at once).
      const found = new Map<string, Margins>();
      for (const r of list.slice(0, MARGINS_FOR)) {
        const full = await tuningApi.stored(r.id);
        found.set(r.id, full.result.margins);
        setMargins(new Map(found));
      }
    } catch (e) {
      setFailure(failureOf(e, 'Read the tuning history'));
    }
  }, [sid]);

  useEffect(() => {
    setRows(null);
    setOpen(null);
    void load();
  }, [load, refresh]);

  async function show(r: TuningRecord) {
    if (open?.id === r.id) {
      setOpen(null);
      return;
    }
    setBusy(r.id);
    setFailure(null);
    try {
      setOpen(await tuningApi.stored(r.id));
    } catch (e) {
      setFailure(failureOf(e, 'Open the stored tuning'));
    } finally {
      setBusy(null);
    }
  }

  const res = open?.result ?? null;
  return (
    <section className="card" data-testid="tuning-history">
      <h2>
        Tuning history of this drive
        <span className="h2-side small muted">
          kept in the store, from every session and gateway{' '}
          <button type="button" className="small-btn" onClick={() => void load()} data-testid="tuning-history-refresh">
            Refresh
          </button>
        </span>
      </h2>
      {failure && <FailureBox f={failure} testid="tuning-history-failure" />}
      {rows === null ? (
        <div className="muted">Reading the tuning history…</div>
      ) : rows.length === 0 ? (
        <div className="muted" data-testid="tuning-history-empty">
          No tuning of this drive is kept in the store yet.
        </div>
      ) : (
        <table className="grid small" data-testid="tuning-history-list">
          <thead>
            <tr>
              <th>Ended</th>
              <th>By</th>
              <th>Kind</th>
              <th>Level</th>
              <th>Outcome</th>
              <th className="num">Ran</th>
              <th>Margins</th>
              <th>Bandwidth</th>
              <th>Gateway</th>
              <th />
            </tr>
          </thead>
          <tbody>
            {rows.map((r) => (
              <tr key={r.id} data-testid="tuning-history-row" data-id={r.id} data-status={r.status} className={open?.id === r.id ? 'tuning-history-current' : undefined}>
                <td>{endedText(r)}</td>
                <td>{r.by}</td>
                <td>{r.kind}</td>
                <td>{r.mode}</td>
                <td data-testid="tuning-history-status">{statusText(r)}</td>
                <td className="mono num">{durationText(r)}</td>
                <td className="mono" data-testid="tuning-history-margins">
                  {margins.has(r.id) ? marginsText(margins.get(r.id)) : '…'}
                </td>
                <td className="mono">{margins.has(r.id) ? bandwidthText(margins.get(r.id)) : '…'}</td>
                <td>{r.gateway}</td>
                <td>
                  <button
                    type="button"
                    className="small-btn"
                    disabled={busy !== null}
                    aria-expanded={open?.id === r.id}
                    onClick={() => void show(r)}
                    data-testid="tuning-history-open"
                  >
                    {open?.id === r.id ? 'Close' : 'Open'}
                  </button>
                </td>
              </tr>
            ))}
          </tbody>
        </table>
      )}
      {open && res && (
        <div className="stack tuning-history-detail" data-testid="tuning-history-detail" data-id={open.id}>
          <h3 className="tuning-h3">
            {open.kind} tuning, level {open.mode}, {statusText(open)}: ended {endedText(open)} on {open.gateway} (session {open.session})
          </h3>
          {res.error && (
            <div className="failure small" role="alert">
              {res.error.name}
              {res.error.code_hex ? ` (${res.error.code_hex})` : ''}
              {res.error.cause ? `: ${res.error.cause}` : ''}
            </div>
          )}
          {res.margins && (
            <div className="small" data-testid="tuning-history-detail-margins">
              Phase margin {withUnit(res.margins.phase_margin_deg, '°')}, gain margin {withUnit(res.margins.gain_margin_db, 'dB')}, crossover{' '}
              {withUnit(res.margins.crossover_hz, 'Hz')}, bandwidth {withUnit(res.margins.bandwidth_hz, 'Hz')}
            </div>
          )}
          {res.bode && <BodePlot bode={res.bode} />}
          {(res.step?.before || res.step?.after) && (
            <div>
              <h3 className="tuning-h3">Step response before and after</h3>
              <StepPlot before={res.step?.before ?? null} after={res.step?.after ?? null} />
            </div>
          )}
          {res.gains.length > 0 && (
            <>
              <h3 className="tuning-h3">Gains</h3>
              <GainTable lines={gainLines(res.gains)} compare testid="tuning-history-gains" />
            </>
          )}
          {res.notes && res.notes.length > 0 && (
            <ul className="small muted tuning-notes">
              {res.notes.map((n) => (
                <li key={n}>{n}</li>
              ))}
            </ul>
          )}
        </div>
      )}
    </section>
  );
}
