/** The notice stack: one box per problem with what failed, why, and what to do. */
import { dismiss, notices } from '../state/notify';
import { useObservable } from '../state/observable';

export function Notices() {
  const list = useObservable(notices);
  if (list.length === 0) return null;
  return (
    <div className="notices" role="status" aria-live="polite">
      {list.map((n) => (
        <div key={n.id} className={`notice notice-${n.kind}`} data-testid={`notice-${n.kind}`}>
          <div className="notice-head">
            <strong className="notice-title">{n.title}</strong>
            <button type="button" className="notice-close" aria-label="Dismiss" onClick={() => dismiss(n.id)}>
              ×
            </button>
          </div>
          {n.message && <div className="notice-msg">{n.message}</div>}
          {n.detail && <div className="notice-detail mono">{n.detail}</div>}
          {n.hint && (
            <div className="notice-hint">
              <span className="hint-label">What to do:</span> {n.hint}
            </div>
          )}
        </div>
      ))}
    </div>
  );
}
