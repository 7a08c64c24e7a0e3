/**
 * Trigger settings (docs/scope.md "Model"): roll, single or normal; a level crossing or an edge
 * (a step) of a channel in a direction, a state change or a fault of the channel's drive; the
 * pre-trigger share of the window, the window and the hold-off.
 *
 * The server compares raw samples, so the level is entered as the channel is shown
 * (engineering x scale + offset) and sent as the raw value it corresponds to; both are shown.
 */
import type { ScopeTrigger, TriggerKind, TriggerMode, TriggerSlope } from '../../api/scope';
import { NumberField } from './NumberField';
import { num, withUnit } from './format';

/** How a channel's raw value becomes the shown one: shown = a * raw + b. */
export interface ShownTransform {
  a: number;
  b: number;
  unit: string;
  rawUnit: string;
  /** The object holds integers: a raw level between two of them means the next one. */
  integer: boolean;
}

/** The raw level (or step, for an edge) the server needs for a shown one. */
export function levelToRaw(kind: TriggerKind, shown: number, t: ShownTransform): number {
  if (t.a === 0) return shown;
  const raw = kind === 'edge' ? Math.abs(shown / t.a) : (shown - t.b) / t.a;
  // 0.1 deg on a 0.0027 deg/inc axis is 36.4 inc: the text the user typed rounds to a raw
  // value that the drive can hold, not to 36.40000001.
  return t.integer ? Math.round(raw) : raw;
}

export function levelToShown(kind: TriggerKind, raw: number, t: ShownTransform): number {
  return kind === 'edge' ? Math.abs(raw * t.a) : t.a * raw + t.b;
}

/** A negative scale turns a rising shown signal into a falling raw one (and back). */
export function slopeToRaw(slope: TriggerSlope, t: ShownTransform): TriggerSlope {
  if (t.a >= 0 || slope === 'either') return slope;
  return slope === 'rising' ? 'falling' : 'rising';
}

const MODES: { id: TriggerMode; text: string; title: string }[] = [
  { id: 'roll', text: 'Roll', title: 'free running, no trigger' },
  { id: 'single', text: 'Single', title: 'arm, capture one window, stop' },
  { id: 'normal', text: 'Normal', title: 'capture a window on every trigger, re-arming after each' },
];

const KINDS: { id: TriggerKind; text: string }[] = [
  { id: 'level', text: 'Level crossing' },
  { id: 'edge', text: 'Edge (step larger than)' },
  { id: 'state', text: 'State change (CiA 402)' },
  { id: 'fault', text: 'Fault (or EMCY)' },
];

interface Props {
  trigger: ScopeTrigger;
  /** Channels the trigger can use: id and label. */
  channels: readonly { id: number; label: string }[];
  transformOf: (id: number) => ShownTransform;
  onChange: (patch: Partial<ScopeTrigger>) => void;
}

export function TriggerPanel({ trigger, channels, transformOf, onChange }: Props) {
  const tr = transformOf(trigger.channel);
  const byLevel = trigger.kind === 'level' || trigger.kind === 'edge';
  const shownLevel = levelToShown(trigger.kind, trigger.level, tr);
  const roll = trigger.mode === 'roll';
  return (
    <div className="scope-trigger" data-testid="scope-trigger">
      <div className="segmented" role="group" aria-label="trigger mode">
        {MODES.map((m) => (
          <button
            key={m.id}
            type="button"
            className={trigger.mode === m.id ? 'on' : ''}
            title={m.title}
            onClick={() => onChange({ mode: m.id })}
            data-testid={`scope-trigger-mode-${m.id}`}
            aria-pressed={trigger.mode === m.id}
          >
            {m.text}
          </button>
        ))}
      </div>
      <div className="scope-form">
        <label>
          <span>Trigger on</span>
          <select value={trigger.kind} disabled={roll} onChange={(e) => onChange({ kind: e.target.value as TriggerKind })} data-testid="scope-trigger-kind">
            {KINDS.map((k) => (
              <option key={k.id} value={k.id}>
                {k.text}
              </option>
            ))}
          </select>
        </label>
        <label>
          <span>Channel</span>
          <select value={trigger.channel} disabled={roll} onChange={(e) => onChange({ channel: Number(e.target.value) })} data-testid="scope-trigger-channel">
            {!channels.some((c) => c.id === trigger.channel) && <option value={trigger.channel}>channel {trigger.channel} (none)</option>}
            {channels.map((c) => (
              <option key={c.id} value={c.id}>
                {c.id} · {c.label}
              </option>
            ))}
          </select>
        </label>
        {byLevel && (
          <>
            <label>
              <span>Slope</span>
              <select value={slopeToRaw(trigger.slope, tr)} disabled={roll} onChange={(e) => onChange({ slope: e.target.value as TriggerSlope })} data-testid="scope-trigger-slope">
                <option value="rising">rising</option>
                <option value="falling">falling</option>
                <option value="either">either</option>
              </select>
            </label>
            <label>
              <span>
                {trigger.kind === 'edge' ? 'Step' : 'Level'} (shown{tr.unit ? `, ${tr.unit}` : ''})
              </span>
              <NumberField
                value={Number(shownLevel.toPrecision(12))}
                disabled={roll}
                onCommit={(v) => onChange({ level: levelToRaw(trigger.kind, v, tr) })}
                testid="scope-trigger-level"
              />
              <span className="muted small mono" data-testid="scope-trigger-level-raw" data-raw={trigger.level}>
                raw {withUnit(num(trigger.level, 10), tr.rawUnit)}
              </span>
            </label>
          </>
        )}
        <label>
          <span>Pre-trigger %</span>
          <NumberField value={Math.round(trigger.pre * 1000) / 10} min={0} max={100} disabled={roll} onCommit={(v) => onChange({ pre: v / 100 })} testid="scope-trigger-pre" />
        </label>
        <label>
          <span>Window s</span>
          <NumberField value={trigger.window_s} min={0.001} max={60} onCommit={(v) => onChange({ window_s: v })} testid="scope-trigger-window" />
        </label>
        <label>
          <span>Hold-off s</span>
          <NumberField value={trigger.holdoff_s} min={0} disabled={trigger.mode !== 'normal'} onCommit={(v) => onChange({ holdoff_s: v })} testid="scope-trigger-holdoff" />
        </label>
      </div>
      <div className="muted small">
        {roll
          ? 'Roll: the view follows the newest samples over the window.'
          : `The window holds ${Math.round(trigger.pre * 100)} % before the trigger sample and ${Math.round((1 - trigger.pre) * 100)} % after it.`}
      </div>
    </div>
  );
}
