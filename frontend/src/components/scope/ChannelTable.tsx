/**
 * The scope's channels (up to 32: 4 drives x 8): session and object, the requested source next to the one the
 * server achieved and its measured rate (never the requested one), units, display scale and
 * offset, show/hide, colour, label, and the newest value shown and raw side by side.
 */
import type { ScopeChannelConfig, ScopeChannelStatus, ScopeSource } from '../../api/scope';
import type { ObjectInfo, SessionInfo } from '../../api/types';
import { NumberField } from './NumberField';
import { ObjectPicker } from './ObjectPicker';
import { hz } from './format';
import { NewestCell, type ScopeSummary } from './live';
import type { Observable } from '../../state/observable';

/** Channels per scope: the backend's MAX_CHANNELS (domain/scope.py), which refuses more. */
export const MAX_CHANNELS = 32;

/** The motion channels, in this order where the profile has them (CiA 402-2): position demand
 * 6062h, position actual 6064h, following error 60F4h, velocity actual 606Ch, torque actual
 * 6077h. */
export const MOTION_SET: readonly string[] = ['0x6062:00', '0x6064:00', '0x60F4:00', '0x606C:00', '0x6077:00'];

const SOURCES: { id: ScopeSource; text: string; title: string }[] = [
  { id: 'auto', text: 'auto', title: 'PDO when the object is in an active TPDO, else the drive recorder when it can record it, else SDO polling' },
  { id: 'pdo', text: 'PDO', title: 'cyclic data (the object must be mapped in an active TPDO while cyclic data runs)' },
  { id: 'recorder', text: 'recorder', title: "the drive's own recorder: every control cycle, uploaded in blocks" },
  { id: 'sdo', text: 'SDO', title: 'polling by SDO reads: as fast as the link answers' },
];

export interface ChannelRowInfo {
  status: ScopeChannelStatus | null;
  object: ObjectInfo | null;
  unit: string;
  rawUnit: string;
}

interface Props {
  channels: readonly ScopeChannelConfig[];
  info: (c: ScopeChannelConfig) => ChannelRowInfo;
  /** The page's summary, for the newest value of each channel. */
  summary: Observable<ScopeSummary>;
  sessions: readonly SessionInfo[];
  objectsOf: (session: string) => readonly ObjectInfo[] | null;
  recordableOf: (session: string) => ReadonlySet<string>;
  colourOf: (id: number) => string;
  onChange: (id: number, patch: Partial<ScopeChannelConfig>) => void;
  onColour: (id: number, colour: string) => void;
  onRemove: (id: number) => void;
  onAdd: () => void;
  /** Adds :data:`MOTION_SET`'s ``motionToAdd`` for the page's drive. */
  onAddMotion: () => void;
  motionToAdd: readonly string[];
  busy: boolean;
}

export function ChannelTable({ channels, info, summary, sessions, objectsOf, recordableOf, colourOf, onChange, onColour, onRemove, onAdd, onAddMotion, motionToAdd, busy }: Props) {
  return (
    <div className="scope-channels" data-testid="scope-channels" data-count={channels.length}>
      {/* 32 rows are taller than a 900 px screen: they scroll in their own box under a header
          that stays, so the plot above and the buttons below stay where they are. */}
      <div className="scope-channel-rows" data-testid="scope-channel-rows">
        <table className="grid scope-grid">
          <thead>
            <tr>
              <th title="show / colour">Show</th>
              <th>#</th>
              <th>Drive (session)</th>
              <th>Object</th>
              <th title="requested source → the source the server achieved, and its measured sample rate">Source → achieved</th>
              <th title="the newest sample: shown (engineering) value, and the raw value the drive sent">Newest: shown · raw</th>
              <th title="shown = engineering × scale + offset">Scale</th>
              <th>Offset</th>
              <th title="requested rate in Hz (SDO poll, recorder sampling); 0: as fast as it goes">Req. Hz</th>
              <th>Label</th>
              <th />
            </tr>
          </thead>
          <tbody>
            {channels.map((c) => {
              const r = info(c);
              const st = r.status;
              const colour = colourOf(c.id);
              return (
                <tr key={c.id} data-testid={`scope-channel-${c.id}`} data-address={c.address} className={c.visible ? '' : 'scope-hidden-row'}>
                  <td className="nowrap">
                    <input
                      type="checkbox"
                      checked={c.visible}
                      onChange={(e) => onChange(c.id, { visible: e.target.checked })}
                      title="show this channel"
                      data-testid={`scope-channel-${c.id}-visible`}
                    />
                    <input type="color" className="scope-colour" value={colour} onChange={(e) => onColour(c.id, e.target.value)} title="colour" data-testid={`scope-channel-${c.id}-colour`} />
                  </td>
                  <td className="mono">{c.id}</td>
                  <td>
                    <select value={c.session} onChange={(e) => onChange(c.id, { session: e.target.value, address: '' })} data-testid={`scope-channel-${c.id}-session`}>
                      {!sessions.some((s) => s.id === c.session) && <option value={c.session}>{c.session} (closed)</option>}
                      {sessions.map((s) => (
                        <option key={s.id} value={s.id}>
                          {s.id}
                        </option>
                      ))}
                    </select>
                  </td>
                  <td className="scope-object-cell">
                    <ObjectPicker
                      objects={objectsOf(c.session)}
                      address={c.address}
                      recordable={recordableOf(c.session)}
                      onPick={(address) => onChange(c.id, { address })}
                      testid={`scope-channel-${c.id}-object`}
                    />
                    {c.address && (
                      <div className="muted small" data-testid={`scope-channel-${c.id}-unit`} title="engineering unit, and the raw unit as the drive holds it">
                        unit {r.unit || '—'} · raw {r.rawUnit || '—'}
                      </div>
                    )}
                  </td>
                  <td>
                    <select value={c.source} onChange={(e) => onChange(c.id, { source: e.target.value as ScopeSource })} data-testid={`scope-channel-${c.id}-source`}>
                      {SOURCES.map((s) => (
                        <option key={s.id} value={s.id} title={s.title}>
                          {s.text}
                        </option>
                      ))}
                    </select>
                    <div
                      className={`scope-achieved${st?.source ? '' : ' muted'}`}
                      data-testid={`scope-channel-${c.id}-achieved`}
                      data-source={st?.source ?? ''}
                      data-rate={st?.rate_hz ?? ''}
                      data-throughput={st?.throughput_hz ?? ''}
                      title="the source the server uses, the sample rate it measured and, when lower, the samples per second that arrived (a recorder uploads between recordings)"
                    >
                      → {st?.source ?? (c.address ? 'not started' : '—')}
                      {st?.rate_hz ? ` · ${hz(st.rate_hz)}` : ''}
                      {st?.rate_hz && st.throughput_hz && st.throughput_hz < 0.95 * st.rate_hz ? ` (${hz(st.throughput_hz)} avg)` : ''}
                    </div>
                    {st?.error && (
                      <div className="scope-error small" data-testid={`scope-channel-${c.id}-error`}>
                        {st.error}
                      </div>
                    )}
                  </td>
                  <NewestCell summary={summary} id={c.id} unit={r.unit} rawUnit={r.rawUnit} />
                  <td>
                    <NumberField className="scope-num" value={c.scale} onCommit={(v) => onChange(c.id, { scale: v })} testid={`scope-channel-${c.id}-scale`} />
                  </td>
                  <td>
                    <NumberField className="scope-num" value={c.offset} onCommit={(v) => onChange(c.id, { offset: v })} testid={`scope-channel-${c.id}-offset`} />
                  </td>
                  <td>
                    <NumberField className="scope-num" value={c.rate_hz ?? 0} min={0} onCommit={(v) => onChange(c.id, { rate_hz: v })} testid={`scope-channel-${c.id}-rate`} />
                  </td>
                  <td>
                    <input
                      className="scope-label"
                      value={c.label ?? ''}
                      placeholder={r.object?.name ?? ''}
                      maxLength={64}
                      onChange={(e) => onChange(c.id, { label: e.target.value })}
                      data-testid={`scope-channel-${c.id}-label`}
                    />
                  </td>
                  <td>
                    <button type="button" className="small-btn" onClick={() => onRemove(c.id)} title="remove this channel" data-testid={`scope-channel-${c.id}-remove`}>
                      ×
                    </button>
                  </td>
                </tr>
              );
            })}
            {channels.length === 0 && (
              <tr>
                <td colSpan={11} className="muted">
                  No channels yet: add one and pick an object.
                </td>
              </tr>
            )}
          </tbody>
        </table>
      </div>
      <div className="scope-row">
        <button type="button" onClick={onAdd} disabled={channels.length >= MAX_CHANNELS || busy} data-testid="scope-add-channel">
          Add channel
        </button>
        <button
          type="button"
          onClick={onAddMotion}
          disabled={motionToAdd.length === 0 || busy}
          data-testid="scope-add-motion"
          title={
            motionToAdd.length > 0
              ? `adds ${motionToAdd.join(', ')} of this drive (position demand and actual, following error, velocity, torque: those its profile has)`
              : "this drive's motion channels are all shown, or no channel is free"
          }
        >
          Add motion channels
        </button>
        <span className="muted small">
          {channels.length} of {MAX_CHANNELS} channels · shown = raw × profile scale × scale + offset
        </span>
      </div>
    </div>
  );
}
