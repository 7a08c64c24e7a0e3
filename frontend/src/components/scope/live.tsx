/**
 * The parts of the Scope page that follow the data a few times a second (the measurements,
 * the newest values, the sample counts and the skipped-frame badge). They read one observable
 * summary, so only they re-render, not the page with its forms.
 */
import type { CursorValue, TraceDef, TraceStats, ViewKind } from './model';
import { Measurements } from './Measurements';
import { num, withUnit } from './format';
import { type Observable, useObservable } from '../../state/observable';

export interface ScopeSummary {
  window: [number, number];
  stats: TraceStats[];
  a: CursorValue[] | null;
  b: CursorValue[] | null;
  cursorA: number | null;
  cursorB: number | null;
  kind: ViewKind;
  /** Samples held in what is shown, and the channels that have some. */
  samples: number;
  channels: number;
  skipped: number;
  /** Newest live sample per channel id: shown and raw. */
  latest: Map<number, { shown: number; raw: number }>;
}

export const EMPTY_SUMMARY: ScopeSummary = {
  window: [0, 1],
  stats: [],
  a: null,
  b: null,
  cursorA: null,
  cursorB: null,
  kind: 'live',
  samples: 0,
  channels: 0,
  skipped: 0,
  latest: new Map(),
};

export function SkippedBadge({ summary }: { summary: Observable<ScopeSummary> }) {
  const { skipped } = useObservable(summary);
  if (skipped <= 0) return null;
  return (
    <span
      className="badge badge-warn"
      data-testid="scope-skipped"
      data-skipped={skipped}
      title="this browser could not keep up: the server dropped whole frames for it (the drive and the other viewers were not slowed)"
    >
      {skipped} frame{skipped === 1 ? '' : 's'} skipped
    </span>
  );
}

export function ViewLine({ summary, name }: { summary: Observable<ScopeSummary>; name: string | null }) {
  const s = useObservable(summary);
  return (
    <span className="small" data-testid="scope-view" data-kind={s.kind} data-channels={s.channels} data-samples={s.samples} data-name={name ?? ''}>
      {s.kind === 'live' && <>Live</>}
      {s.kind === 'capture' && <>Capture · trigger at 0 s</>}
      {s.kind === 'recording' && <>Recording {name}</>} · {s.channels} channel{s.channels === 1 ? '' : 's'} · {s.samples} samples
    </span>
  );
}

export function NewestCell({ summary, id, unit, rawUnit }: { summary: Observable<ScopeSummary>; id: number; unit: string; rawUnit: string }) {
  const latest = useObservable(summary).latest.get(id) ?? null;
  return (
    <td className="mono nowrap" data-testid={`scope-channel-${id}-latest`} data-shown={latest ? String(latest.shown) : ''} data-raw={latest ? String(latest.raw) : ''}>
      {latest ? (
        <>
          {withUnit(num(latest.shown), unit)} <span className="muted">· raw {withUnit(num(latest.raw, 10), rawUnit)}</span>
        </>
      ) : (
        <span className="muted">—</span>
      )}
    </td>
  );
}

export function LiveMeasurements({ summary, traces, onToggle }: { summary: Observable<ScopeSummary>; traces: readonly TraceDef[]; onToggle: (key: string) => void }) {
  return <Measurements traces={traces} summary={useObservable(summary)} onToggle={onToggle} />;
}
