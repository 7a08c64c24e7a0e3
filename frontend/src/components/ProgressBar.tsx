/** A horizontal progress bar with a label; `fraction` null shows an indeterminate bar. */
export function ProgressBar({ fraction, label, testid }: { fraction: number | null; label?: string; testid?: string }) {
  const pct = fraction === null ? null : Math.round(Math.max(0, Math.min(1, fraction)) * 100);
  return (
    <div className="progress" data-testid={testid} role="progressbar" aria-valuemin={0} aria-valuemax={100} aria-valuenow={pct ?? undefined}>
      <div className={`progress-track${pct === null ? ' indeterminate' : ''}`}>
        <div className="progress-fill" style={{ width: pct === null ? '30%' : `${pct}%` }} />
      </div>
      {label ? <span className="progress-label small">{label}</span> : null}
    </div>
  );
}
