/**
 * The viser 3D viewer in an iframe (GET /api/v1/viewer -> {enabled, url, port}), or a clear
 * message why it is not shown: switched off, not built into this server (404), or the server
 * did not answer. `compact` is the small panel of the Operation page.
 */
import { useEffect, useState } from 'react';
import { ApiError, operationApi } from '../../api/client';
import type { ViewerInfo } from '../../api/types';
import { type ViewerTarget, viewerTarget } from '../../lib/viewer';

type Load = { kind: 'loading' } | { kind: 'done'; info: ViewerInfo; target: ViewerTarget } | { kind: 'failed'; reason: string };

export function useViewer(): Load {
  const [load, setLoad] = useState<Load>({ kind: 'loading' });
  useEffect(() => {
    let alive = true;
    operationApi.viewer().then(
      (info) => alive && setLoad({ kind: 'done', info, target: viewerTarget(info, window.location) }),
      (e: unknown) => {
        if (!alive) return;
        const reason =
          e instanceof ApiError && e.status === 404
            ? 'this servodesk server has no 3D viewer (GET /api/v1/viewer is not there)'
            : e instanceof ApiError
              ? e.body.message
              : String(e);
        setLoad({ kind: 'failed', reason });
      },
    );
    return () => {
      alive = false;
    };
  }, []);
  return load;
}

export function ViewerFrame({ compact = false, sid }: { compact?: boolean; sid?: string }) {
  const load = useViewer();
  const testid = compact ? 'viewer-compact' : 'viewer';
  if (load.kind === 'loading') return <div className="muted">Asking the server for the 3D viewer…</div>;
  const reason = load.kind === 'failed' ? load.reason : load.target.ok ? null : load.target.reason;
  if (reason !== null || load.kind !== 'done' || !load.target.ok) {
    return (
      <div className="viewer-off" data-testid={`${testid}-disabled`}>
        <strong>3D view not available.</strong> {reason}
        {!compact && (
          <div className="muted small">
            The viewer runs with the backend (servodesk serve); when it is switched off, the other pages work as usual.
          </div>
        )}
      </div>
    );
  }
  const src = load.target.src;
  return (
    <div className={`viewer-wrap${compact ? ' viewer-compact' : ''}`}>
      <iframe
        src={src}
        title={sid ? `3D view of ${sid}` : '3D view'}
        className="viewer-frame"
        data-testid={`${testid}-frame`}
        allow="fullscreen"
      />
      <div className="muted small viewer-foot">
        viser at <a href={src} target="_blank" rel="noreferrer" className="mono">{src}</a>
      </div>
    </div>
  );
}
