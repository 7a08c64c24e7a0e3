/**
 * A modal confirmation for actions that cannot be undone (restore defaults): it says what
 * will happen, and the confirm button names the action. Escape or Cancel closes it.
 */
import { type ReactNode, useEffect, useRef } from 'react';

export function ConfirmDialog({
  title,
  children,
  confirmLabel,
  onConfirm,
  onCancel,
  busy = false,
  testid = 'confirm-dialog',
}: {
  title: string;
  children: ReactNode;
  confirmLabel: string;
  onConfirm: () => void;
  onCancel: () => void;
  busy?: boolean;
  testid?: string;
}) {
  const cancelRef = useRef<HTMLButtonElement>(null);
  useEffect(() => {
    // Focus Cancel, not the destructive button: Enter must not confirm by accident.
    cancelRef.current?.focus();
    const onKey = (e: KeyboardEvent) => {
      if (e.key === 'Escape') onCancel();
    };
    window.addEventListener('keydown', onKey);
    return () => window.removeEventListener('keydown', onKey);
  }, [onCancel]);
  return (
    <div className="modal-backdrop" onClick={onCancel}>
      <div className="modal" role="dialog" aria-modal="true" aria-labelledby={`${testid}-title`} data-testid={testid} onClick={(e) => e.stopPropagation()}>
        <h2 id={`${testid}-title`}>{title}</h2>
        <div className="modal-body">{children}</div>
        <div className="modal-actions">
          <button type="button" ref={cancelRef} onClick={onCancel} data-testid={`${testid}-cancel`} disabled={busy}>
            Cancel
          </button>
          <button type="button" className="warn-btn" onClick={onConfirm} data-testid={`${testid}-confirm`} disabled={busy}>
            {busy ? 'Working…' : confirmLabel}
          </button>
        </div>
      </div>
    </div>
  );
}
