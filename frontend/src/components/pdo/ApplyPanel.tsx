/**
 * Plan, confirm and apply a mapping (docs/pdo.md "REST"): POST /pdo/plan shows the ordered
 * steps of the family's procedure (CiA 301 §7.5.2.35/36: pre-operational, disable by COB-ID
 * bit 31, count 0, entries, count, enable, previous NMT state; HIWIN 000 §2.8.1/§2.8.2 for the
 * sync manager assignment) with why each is there; the person confirms; POST /pdo/apply runs
 * them with progress over the WebSocket (operation "pdo") and answers the report: done or the
 * step that failed, whether the old mapping was put back, whether the read-back verified.
 */
import { useEffect, useRef, useState } from 'react';
import { PdoRefusedError, pdoApi } from '../../api/pdo';
import type { ErrorInfo, PdoApplyReport, PdoLayout, PdoPlan, PdoProblem, PdoStep } from '../../api/types';
import { type Failure, failureOf } from '../../lib/codes';
import { watchProgress } from '../../ws/progress';
import { ControlNote, useWriteGate } from '../ControlNote';
import { FailureBox } from '../FailureBox';
import { ProgressBar } from '../ProgressBar';

function stepValue(s: PdoStep): string {
  if (s.kind === 'nmt') return `NMT ${s.command ?? ''}`.trim();
  return s.value_hex ?? `0x${s.value.toString(16).toUpperCase()}`;
}

function StepTable({ steps, done, failed, testid }: { steps: readonly PdoStep[]; done: number | null; failed: number | null; testid: string }) {
  return (
    <div className="bk-table-wrap pdo-steps">
      <table className="grid bk-table" data-testid={testid}>
        <thead>
          <tr>
            <th className="num">#</th>
            <th>Why</th>
            <th>Object</th>
            <th>Value</th>
            {done !== null && <th />}
          </tr>
        </thead>
        <tbody>
          {steps.map((s, i) => (
            <tr key={i} className={failed === i ? 'pdo-step-failed' : ''} data-testid={`${testid}-${i}`}>
              <td className="num mono muted">{i + 1}</td>
              <td>{s.why}</td>
              <td className="mono nowrap">{s.kind === 'nmt' ? <span className="muted">NMT</span> : (s.address ?? '')}</td>
              <td className="mono nowrap">{stepValue(s)}</td>
              {done !== null && (
                <td className="nowrap small">{failed === i ? <span className="pdo-over-text">failed</span> : i < done ? '✓' : <span className="muted">not run</span>}</td>
              )}
            </tr>
          ))}
        </tbody>
      </table>
    </div>
  );
}

function Report({ r }: { r: PdoApplyReport }) {
  const failedAt = r.failed_step ? r.steps.findIndex((s) => s === r.failed_step || (s.why === r.failed_step?.why && s.address === r.failed_step?.address && s.value === r.failed_step?.value)) : -1;
  const cls = r.ok ? 'bk-ok' : 'bk-bad';
  return (
    <div className="stack pdo-report" data-testid="pdo-report" data-ok={r.ok} data-dry-run={r.dry_run}>
      <div className={cls}>
        <strong data-testid="pdo-report-result">
          {r.dry_run
            ? r.ok
              ? `Dry run: ${r.steps.length} steps would be written; nothing was written.`
              : 'Dry run failed; nothing was written.'
            : r.ok
              ? `Applied: ${r.done} of ${r.steps.length} steps in ${r.duration_s.toFixed(2)} s.`
              : `Failed after ${r.done} of ${r.steps.length} steps (${r.duration_s.toFixed(2)} s).`}
        </strong>
        {!r.dry_run && (
          <span data-testid="pdo-report-flags">
            Read back: {r.verified ? <span className="pdo-ok-text">verified</span> : <span className="pdo-over-text">not verified</span>}
            {' · '}
            Previous mapping put back: {r.rolled_back ? 'yes' : 'no'}
          </span>
        )}
        {r.error && <span data-testid="pdo-report-error">{r.error}</span>}
        {r.rollback_error && <span data-testid="pdo-report-rollback-error">Putting the previous mapping back failed: {r.rollback_error}</span>}
        {r.failed_step && (
          <span data-testid="pdo-report-failed-step">
            Failed step: {r.failed_step.why} ({r.failed_step.kind === 'nmt' ? 'NMT' : r.failed_step.address} = {stepValue(r.failed_step)})
          </span>
        )}
      </div>
      {r.steps.length > 0 && <StepTable steps={r.steps} done={r.dry_run ? null : r.done} failed={failedAt >= 0 ? failedAt : null} testid="pdo-report-steps" />}
    </div>
  );
}

export function ApplyPanel({
  sid,
  layout,
  blocked,
  errors,
  onRefused,
  onApplied,
}: {
  sid: string;
  layout: PdoLayout;
  /** Why apply is not possible now (problems, checking, nothing changed, fixed), or null. */
  blocked: string | null;
  errors: readonly ErrorInfo[];
  /** The server refused the mapping: its problems, to show in place. */
  onRefused: (problems: PdoProblem[]) => void;
  onApplied: (r: PdoApplyReport) => void;
}) {
  const key = JSON.stringify(layout);
  const [plan, setPlan] = useState<{ plan: PdoPlan; key: string } | null>(null);
  const [busy, setBusy] = useState<'plan' | 'apply' | 'dry' | null>(null);
  const [failure, setFailure] = useState<Failure | null>(null);
  const [progress, setProgress] = useState<{ fraction: number; message: string | null } | null>(null);
  const [report, setReport] = useState<PdoApplyReport | null>(null);
  const mounted = useRef(true);
  // A dry run and the apply run against the drive: they need control (the plan does not).
  const noControl = useWriteGate(sid).write;
  useEffect(() => {
    mounted.current = true;
    return () => {
      mounted.current = false;
    };
  }, []);

  // An edit after planning makes the plan stale: it must be planned again.
  const current = plan && plan.key === key ? plan.plan : null;

  function refused(e: unknown, action: string) {
    if (e instanceof PdoRefusedError) onRefused(e.problems);
    setFailure(failureOf(e, action, errors));
  }

  async function makePlan() {
    setBusy('plan');
    setFailure(null);
    setReport(null);
    try {
      const p = await pdoApi.plan(sid, layout);
      if (mounted.current) setPlan({ plan: p, key });
    } catch (e) {
      if (mounted.current) refused(e, 'Plan the mapping');
    } finally {
      if (mounted.current) setBusy(null);
    }
  }

  async function apply(dryRun: boolean) {
    setBusy(dryRun ? 'dry' : 'apply');
    setFailure(null);
    setReport(null);
    setProgress({ fraction: 0, message: dryRun ? 'Dry run…' : 'Starting…' });
    const watch = watchProgress(sid, 'pdo', (m) => {
      if (mounted.current) setProgress({ fraction: m.fraction, message: m.message });
    });
    try {
      await watch.ready;
      const r = await pdoApi.apply(sid, { ...layout, dry_run: dryRun });
      if (!mounted.current) return;
      setReport(r);
      if (!dryRun) setPlan(null);
      onApplied(r);
    } catch (e) {
      if (mounted.current) refused(e, dryRun ? 'Dry-run the mapping' : 'Apply the mapping');
    } finally {
      watch.close();
      if (mounted.current) {
        setBusy(null);
        setProgress(null);
      }
    }
  }

  return (
    <section className="card" data-testid="pdo-apply-card">
      <h2>
        Apply
        <span className="h2-side small muted">nothing is written until you confirm</span>
      </h2>
      <div className="bk-row">
        <button
          type="button"
          className="primary"
          disabled={!!blocked || busy !== null}
          onClick={() => void makePlan()}
          data-testid="pdo-review"
          title={blocked ?? 'show the steps that would be written'}
        >
          {busy === 'plan' ? 'Planning…' : 'Review and apply…'}
        </button>
        <button
          type="button"
          disabled={!!blocked || busy !== null || noControl !== null}
          onClick={() => void apply(true)}
          data-testid="pdo-dry-run"
          title={blocked ?? noControl ?? 'run the plan against the drive without writing'}
        >
          {busy === 'dry' ? 'Dry run…' : 'Dry run'}
        </button>
        {blocked && (
          <span className="muted small" data-testid="pdo-apply-blocked">
            {blocked}
          </span>
        )}
      </div>
      <ControlNote sid={sid} what="Dry run and Write are disabled; Review shows the steps" testid="pdo-apply-control-note" />
      {failure && <FailureBox f={failure} testid="pdo-apply-failure" />}
      {current && !report && (
        <div className="stack pdo-plan" data-testid="pdo-plan">
          <div>
            <strong>{current.steps.length} steps</strong>
            {current.touched.length > 0 && <span> change {current.touched.join(', ')}</span>}. They run in this order; if one fails, the previous mapping is
            written back.
          </div>
          <StepTable steps={current.steps} done={null} failed={null} testid="pdo-plan-steps" />
          <div className="bk-row">
            <button
              type="button"
              className="go"
              disabled={busy !== null || !!blocked || noControl !== null}
              title={noControl ?? undefined}
              onClick={() => void apply(false)}
              data-testid="pdo-apply-confirm"
            >
              {busy === 'apply' ? 'Writing…' : `Write ${current.steps.length} steps to the drive`}
            </button>
            <button type="button" disabled={busy !== null} onClick={() => setPlan(null)} data-testid="pdo-plan-cancel">
              Cancel
            </button>
          </div>
        </div>
      )}
      {plan && !current && !report && <div className="muted small">The mapping changed since the plan: review it again.</div>}
      {progress && <ProgressBar fraction={progress.fraction} label={progress.message ?? undefined} testid="pdo-apply-progress" />}
      {report && <Report r={report} />}
    </section>
  );
}
