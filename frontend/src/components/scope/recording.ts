/**
 * A recording from the server (GET /scope/capture, POST /scope/import) as the page opens it:
 * sample times on the backend clock, raw values, and each channel's names, units and scales.
 *
 * Times are seconds from `t_ref` (domain/scope_export.py `Recording.to_json`); times already on
 * the backend clock are taken as they are. `scale` (and `eng_scale`) is the profile's raw to
 * engineering factor; a capture adds the page's display scale and offset of each channel
 * (`display_scale`, `offset`), which a file does not have. Missing samples (null, a CSV's
 * "nan") are left out.
 */
import type { RecordingChannel, ScopeRecording } from '../../api/scope';
import type { OpenRecording } from './model';

/** Backend times are seconds since 1970: anything below this is an offset from t_ref. */
const ABSOLUTE_AFTER_S = 1e8;

export interface RecordingMeta {
  id: number;
  label: string;
  name: string | null;
  unit: string;
  rawUnit: string;
  engScale: number;
  scale: number;
  offset: number;
  address: string | null;
  session: string | null;
  source: string | null;
  samples: number;
}

export interface NormalisedRecording {
  open: OpenRecording;
  meta: RecordingMeta[];
  samples: number;
}

function finite(x: unknown, fallback: number): number {
  return typeof x === 'number' && Number.isFinite(x) ? x : fallback;
}

function text(x: unknown): string | null {
  return typeof x === 'string' && x !== '' ? x : null;
}

export function normaliseRecording(rec: ScopeRecording, name: string | null = null): NormalisedRecording {
  const tRef = finite(rec.t_ref, 0);
  const meta: RecordingMeta[] = [];
  let total = 0;
  const channels = (rec.channels ?? []).map((c: RecordingChannel) => {
    const ts = c.t ?? [];
    const vs = c.v ?? [];
    const n = Math.min(ts.length, vs.length);
    // Offsets from t_ref unless the times are already on the backend clock.
    let firstT: number | null = null;
    for (let i = 0; i < n && firstT === null; i++) if (typeof ts[i] === 'number') firstT = ts[i] as number;
    const base = firstT !== null && Math.abs(firstT) < ABSOLUTE_AFTER_S ? tRef : 0;
    const t = new Float64Array(n);
    const v = new Float64Array(n);
    let k = 0;
    let last = -Infinity;
    for (let i = 0; i < n; i++) {
      const ti = ts[i];
      const vi = vs[i];
      if (typeof ti !== 'number' || typeof vi !== 'number' || !Number.isFinite(vi)) continue;
      const at = base + ti;
      if (!(at > last)) continue;
      t[k] = at;
      v[k] = vi;
      last = at;
      k++;
    }
    total += k;
    meta.push({
      id: c.id,
      label: text(c.label) ?? text(c.name) ?? text(c.address) ?? `channel ${c.id}`,
      name: text(c.name),
      unit: text(c.unit) ?? '',
      rawUnit: text(c.raw_unit) ?? '',
      engScale: finite(c.eng_scale, finite(c.scale, 1)),
      scale: finite(c.display_scale, 1),
      offset: finite(c.offset, 0),
      address: text(c.address),
      session: text(c.session),
      source: text(c.source),
      samples: k,
    });
    return { id: c.id, t: t.subarray(0, k), v: v.subarray(0, k) };
  });
  let trigger: number | null = typeof rec.trigger_time === 'number' && Number.isFinite(rec.trigger_time) ? rec.trigger_time : null;
  if (trigger !== null && Math.abs(trigger) < ABSOLUTE_AFTER_S && Math.abs(tRef) >= ABSOLUTE_AFTER_S) trigger += tRef;
  return { open: { triggerTime: trigger, channels, name }, meta, samples: total };
}
