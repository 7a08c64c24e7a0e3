/**
 * 3D view: the viser twin of the axes, served by the backend beside the UI and embedded here
 * (GET /api/v1/viewer). When the viewer is off the page says so and why.
 */
import { ViewerFrame } from '../components/operation/ViewerFrame';
import '../components/operation/operation.css';
import type { PageProps } from './registry';

export function ViewerPage({ sid }: PageProps) {
  return (
    <div className="stack viewer-page" data-testid="viewer-page">
      <section className="card">
        <h2>
          Live 3D twin <span className="h2-side muted">viser · drive {sid}</span>
        </h2>
        <ViewerFrame sid={sid} />
      </section>
    </div>
  );
}
