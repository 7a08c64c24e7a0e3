/**
 * One PDO of the editor: its bit budget, its communication parameters (where the family has
 * them: CiA 301 §7.5.2.35 / §7.5.2.37), and its entries with byte and bit offsets, object,
 * type, unit and live value.
 *
 * Entries are edited by HTML5 drag and drop (objects from the palette, entries within the PDO
 * or to another PDO of the same direction) and, for keyboards and touchpads, by a select with
 * an Add button, up/down buttons and a remove button per entry. Problems the server found are
 * shown next to the entry, field or PDO they name.
 */
import { type DragEvent, useState } from 'react';
import type { MappableObject, PdoEntryOut, PdoKind } from '../../api/types';
import type { Observable } from '../../state/observable';
import { useObservable } from '../../state/observable';
import { BudgetBar, NumberBox, ProblemList, decimalParser, intParser } from './fields';
import { type PdoLive, liveKey } from './pdoLive';
import {
  DRAG_MIME,
  type DraftComm,
  type DraftEntry,
  type DraftPdo,
  type DragItem,
  type DropTarget,
  type ObjectDescription,
  type PdoProblems,
  type TransmissionChoice,
  bitBudget,
  cobIdText,
  dataTypeName,
  decodeDrag,
  encodeDrag,
  entryAddress,
  entryOffsets,
  entryRawHex,
  formatLive,
  frameLength,
  hex,
  inhibitMs,
  inhibitRaw,
  isPadding,
  paddingName,
  parseCobId,
  pdoKey,
  transmissionChoice,
  transmissionFromChoice,
  transmissionOptions,
  transmissionText,
} from './pdoModel';

/** Shared drag state: what is being dragged now (read on dragover, where DataTransfer is not). */
export interface DragState {
  dragging: DragItem | null;
  /** A drag started (the page sets `dragging` once the browser has started it). */
  begin: (d: DragItem) => void;
  /** The drag ended (dropped or cancelled). */
  end: () => void;
}

export function startDrag(e: DragEvent, item: DragItem, drag: DragState, text: string): void {
  e.dataTransfer.setData(DRAG_MIME, encodeDrag(item));
  e.dataTransfer.setData('text/plain', text);
  e.dataTransfer.effectAllowed = item.kind === 'object' ? 'copy' : 'move';
  drag.begin(item);
}

/** A padding entry the family allows (LECSN Reserved, 004 §20.1.2: 8 or 16 bits). */
export const RESERVED_ENTRIES: readonly DraftEntry[] = [
  { index: 0, subindex: 0, bits: 8 },
  { index: 0, subindex: 0, bits: 16 },
];

function LiveCell({ live, address, rawUnit, testid }: { live: Observable<PdoLive>; address: string; rawUnit: string | null; testid: string }) {
  const l = useObservable(live);
  const v = l.values[liveKey(address)];
  if (!v) return <span className="muted" data-testid={testid}>—</span>;
  const t = formatLive(v, rawUnit);
  // Greyed when the server says the link cannot vouch for it (EtherCAT link lost), or
  // when no update came for 2 s.
  const stale = v.stale === true || (l.received !== null && Date.now() - l.received > 2000);
  return (
    <span className={`pdo-live${stale ? ' stale' : ''}`} data-testid={testid} data-raw={String(v.value)}>
      <span className="mono" title="raw value, as the frame carries it">
        {t.raw}
      </span>
      {t.eng !== null && (
        <>
          <span className="muted"> · </span>
          <span className="mono" title="engineering value">
            {t.eng}
          </span>
        </>
      )}
    </span>
  );
}

/** Frames per second of this PDO while cyclic data runs. */
function RateBadge({ live, name, testid }: { live: Observable<PdoLive>; name: string; testid: string }) {
  const rate = useObservable(live).rates[name];
  if (rate === undefined) return null;
  return (
    <span className="mono" data-testid={testid} title="frames per second of this PDO">
      {rate.toFixed(rate < 10 ? 1 : 0)} Hz ·{' '}
    </span>
  );
}

function CommEditor({
  pdo,
  comm,
  problems,
  readOnly,
  onChange,
}: {
  pdo: DraftPdo;
  comm: DraftComm;
  problems: PdoProblems | undefined;
  readOnly: boolean;
  onChange: (patch: Partial<DraftComm>) => void;
}) {
  const id = (f: string) => `pdo-${pdo.name}-${f}`;
  const tx = pdo.direction === 'tx';
  const choice = transmissionChoice(comm.transmission_type);
  const fieldProblems = (f: string) => <ProblemList problems={problems?.fields.get(f)} testid={id(`${f}-problems`)} />;
  return (
    <div className="pdo-comm" data-testid={id('comm')}>
      <label>
        <span>COB-ID (hex)</span>
        <NumberBox
          value={comm.cob_id}
          onChange={(v) => onChange({ cob_id: v })}
          parse={parseCobId}
          format={cobIdText}
          testid={id('cob_id')}
          label="COB-ID"
          disabled={readOnly}
          width={70}
          title="11-bit CAN identifier (COB-ID bits 10..0)"
        />
        {fieldProblems('cob_id')}
      </label>
      <label className="pdo-check" title="COB-ID bit 31 clear: the PDO is valid and goes on the bus">
        <input
          type="checkbox"
          checked={comm.enabled}
          disabled={readOnly}
          onChange={(e) => onChange({ enabled: e.target.checked })}
          data-testid={id('enabled')}
        />
        <span>enabled</span>
        {fieldProblems('enabled')}
      </label>
      {tx && (
        <label className="pdo-check" title="COB-ID bit 30 clear: the drive answers a remote request (RTR) for this PDO">
          <input
            type="checkbox"
            checked={comm.rtr_allowed}
            disabled={readOnly}
            onChange={(e) => onChange({ rtr_allowed: e.target.checked })}
            data-testid={id('rtr_allowed')}
          />
          <span>RTR allowed</span>
          {fieldProblems('rtr_allowed')}
        </label>
      )}
      <label>
        <span>Transmission type</span>
        <span className="pdo-inline">
          <select
            value={choice}
            disabled={readOnly}
            data-testid={id('transmission_type')}
            title={transmissionText(comm.transmission_type)}
            onChange={(e) => onChange({ transmission_type: transmissionFromChoice(e.target.value as TransmissionChoice, comm.transmission_type) })}
          >
            {transmissionOptions(pdo.direction).map((o) => (
              <option key={o.value} value={o.value}>
                {o.label}
              </option>
            ))}
            {choice === 'reserved' && <option value="reserved">{comm.transmission_type} · reserved</option>}
          </select>
          {choice === 'n' && (
            <>
              <span className="muted small">n =</span>
              <NumberBox
                value={comm.transmission_type}
                onChange={(v) => onChange({ transmission_type: v })}
                parse={intParser(1, 240)}
                testid={id('transmission_n')}
                label="Every n-th SYNC"
                disabled={readOnly}
                width={50}
              />
            </>
          )}
        </span>
        {fieldProblems('transmission_type')}
      </label>
      {tx && (
        <label>
          <span>Inhibit time (ms)</span>
          <span className="pdo-inline">
            <NumberBox
              value={inhibitMs(comm.inhibit_time)}
              onChange={(v) => onChange({ inhibit_time: inhibitRaw(v) })}
              parse={decimalParser(0, 6553.5, 1)}
              testid={id('inhibit_time')}
              label="Inhibit time"
              disabled={readOnly}
              width={64}
              title="minimum time between two transmissions of this TPDO"
            />
            <span className="muted small mono" data-testid={id('inhibit_raw')} title="the raw value the drive holds (100 µs units)">
              = {comm.inhibit_time} × 100 µs
            </span>
          </span>
          {fieldProblems('inhibit_time')}
        </label>
      )}
      <label>
        <span>{tx ? 'Event timer (ms)' : 'Event timer / deadline (ms)'}</span>
        <NumberBox
          value={comm.event_timer}
          onChange={(v) => onChange({ event_timer: v })}
          parse={intParser(0, 65535)}
          testid={id('event_timer')}
          label="Event timer"
          disabled={readOnly}
          width={64}
          title={tx ? 'send at least every this many ms (0: off)' : 'RPDO deadline monitoring: expect the PDO within this many ms (0: off)'}
        />
        {fieldProblems('event_timer')}
      </label>
      {tx && (
        <label>
          <span>SYNC start</span>
          <NumberBox
            value={comm.sync_start}
            onChange={(v) => onChange({ sync_start: v })}
            parse={intParser(0, 240)}
            testid={id('sync_start')}
            label="SYNC start value"
            disabled={readOnly}
            width={50}
            title="SYNC counter value of the first transmission (0: not used)"
          />
          {fieldProblems('sync_start')}
        </label>
      )}
    </div>
  );
}

export interface PdoCardProps {
  pdo: DraftPdo;
  kind: PdoKind;
  maxBits: number;
  maxEntries: number;
  active: boolean;
  changed: boolean;
  readOnly: boolean;
  problems: PdoProblems | undefined;
  describe: ReadonlyMap<string, ObjectDescription>;
  rawUnits: ReadonlyMap<string, string>;
  /** Objects of this PDO's direction, for the keyboard Add. */
  mappable: readonly MappableObject[];
  /** The family allows Reserved padding entries (telegram). */
  padding: boolean;
  /** This PDO's entries as the server laid them out (the latest check of the draft, else the
   * drive's): the name of a fixed telegram's word that is no object (telegram 1's STW1,
   * NSOLL_A: 004 §20.3 (1)) comes from there. */
  slots?: readonly PdoEntryOut[];
  live: Observable<PdoLive>;
  drag: DragState;
  canDropHere: (item: DragItem) => boolean;
  onDrop: (item: DragItem, target: DropTarget) => void;
  onAdd: (entry: DraftEntry) => void;
  onRemove: (at: number) => void;
  onMove: (from: number, to: number) => void;
  onComm: (patch: Partial<DraftComm>) => void;
}

/** The server's slot for a padding entry when it names a telegram word (STW1, ...): the same
 * entry at the same place, and a name other than plain padding. */
function telegramWord(slot: PdoEntryOut | undefined, e: { index: number; subindex: number; bits: number }): PdoEntryOut | null {
  if (!slot || !slot.padding || slot.index !== e.index || slot.subindex !== e.subindex || slot.bits !== e.bits) return null;
  return slot.name && slot.name !== 'Reserved' && !slot.name.startsWith('dummy') ? slot : null;
}

export function PdoCard(props: PdoCardProps) {
  const { pdo, kind, maxBits, maxEntries, problems, readOnly, drag } = props;
  const key = pdoKey(pdo);
  const [dropAt, setDropAt] = useState<number | null>(null);
  const [pick, setPick] = useState('');
  const budget = bitBudget(pdo.entries, maxBits, maxEntries);
  const offsets = entryOffsets(pdo.entries);
  const frame = frameLength(budget.bytes, kind);
  const id = (f: string) => `pdo-${pdo.name}-${f}`;

  const accepts = (e: DragEvent): DragItem | null => {
    if (readOnly) return null;
    const item = drag.dragging;
    if (item && props.canDropHere(item)) return item;
    // A drag from elsewhere (no shared state): accept our type, check on drop.
    if (!item && Array.from(e.dataTransfer.types).includes(DRAG_MIME)) return { kind: 'entry', pdo: '', from: -1 };
    return null;
  };

  const over = (at: number) => (e: DragEvent) => {
    const item = accepts(e);
    if (!item) return;
    e.preventDefault();
    e.stopPropagation();
    e.dataTransfer.dropEffect = item.kind === 'object' ? 'copy' : 'move';
    if (dropAt !== at) setDropAt(at);
  };

  const drop = (at: number) => (e: DragEvent) => {
    e.preventDefault();
    e.stopPropagation();
    setDropAt(null);
    const item = decodeDrag(e.dataTransfer.getData(DRAG_MIME)) ?? drag.dragging;
    drag.end();
    if (item && props.canDropHere(item)) props.onDrop(item, { pdo: key, at });
  };

  const leave = (e: DragEvent) => {
    // Only when the pointer leaves the table, not when it moves between its rows.
    if (!e.currentTarget.contains(e.relatedTarget as Node | null)) setDropAt(null);
  };

  const addOptions: Array<{ value: string; label: string; entry: DraftEntry }> = [
    ...props.mappable.map((o) => ({
      value: o.address,
      label: `${o.address} ${o.name} (${dataTypeName(o.data_type)}, ${o.bits} bits)`,
      entry: { index: o.index, subindex: o.subindex, bits: o.bits },
    })),
    ...(props.padding ? RESERVED_ENTRIES.map((r) => ({ value: `reserved-${r.bits}`, label: paddingName(r), entry: r })) : []),
  ];

  const rowDrop = (i: number) => (dropAt === i ? ' pdo-drop-before' : '');
  const dragOk = drag.dragging !== null && !readOnly && props.canDropHere(drag.dragging);

  return (
    <section
      className={`card pdo-card${props.active ? '' : ' inactive'}${dragOk ? ' drop-ok' : ''}`}
      data-testid={`pdo-card-${pdo.name}`}
      data-pdo={pdo.name}
      data-direction={pdo.direction}
      data-active={props.active}
    >
      <h2>
        <span data-testid={id('name')}>{pdo.name}</span>
        <span className="muted mono pdo-idx" title="mapping object · communication object">
          {hex(pdo.mapping_index)}
          {pdo.comm_index !== null ? ` · ${hex(pdo.comm_index)}` : ''}
        </span>
        {props.changed && (
          <span className="badge badge-warn" data-testid={id('changed')} title="differs from the drive; not written until you apply">
            EDITED
          </span>
        )}
        {!props.active && (
          <span className="badge" title={kind === 'ethercat' ? 'not assigned to its sync manager' : 'disabled (COB-ID bit 31 set)'}>
            NOT ON THE BUS
          </span>
        )}
        <span className="h2-side small">
          <RateBadge live={props.live} name={pdo.name} testid={id('rate')} />
          {pdo.direction === 'rx' ? 'master → drive' : 'drive → master'}
        </span>
      </h2>
      <BudgetBar
        used={budget.bits}
        max={maxBits}
        over={budget.over}
        testid={id('budget')}
        label={
          <>
            <span className="mono">
              {budget.bits} / {maxBits} bits
            </span>{' '}
            · {budget.bytes} bytes{frame !== null && kind !== 'canopen' && frame !== budget.bytes ? ` (frame ${frame})` : ''} ·{' '}
            <span className={budget.tooManyEntries ? 'pdo-over-text' : ''}>
              {budget.entries} / {maxEntries} entries
            </span>
          </>
        }
      />
      <ProblemList problems={problems?.pdo} testid={id('problems')} />
      {pdo.comm && <CommEditor pdo={pdo} comm={pdo.comm} problems={problems} readOnly={readOnly} onChange={props.onComm} />}
      <table className="grid pdo-entries" onDragLeave={leave} data-testid={id('entries')}>
        <thead>
          <tr>
            <th className="num" title="position in the mapping (sub-index)">#</th>
            <th className="num" title="byte offset in the frame">Byte</th>
            <th className="num" title="bit offset within that byte">Bit</th>
            <th className="num">Bits</th>
            <th>Object</th>
            <th>Name</th>
            <th>Type</th>
            <th>Unit</th>
            <th title="the latest value from the cyclic data: raw (as the frame carries it) · engineering">Live (raw · engineering)</th>
            {!readOnly && <th />}
          </tr>
        </thead>
        <tbody>
          {pdo.entries.map((e, i) => {
            const address = entryAddress(e);
            const d = address ? props.describe.get(address.toUpperCase()) : undefined;
            const word = address ? null : telegramWord(props.slots?.[i], e);
            const off = offsets[i];
            const eProblems = problems?.entries.get(i);
            return (
              <tr
                key={`${i}-${entryRawHex(e)}`}
                className={`pdo-entry${rowDrop(i)}${eProblems ? ' has-problem' : ''}${isPadding(e) ? ' padding' : ''}`}
                draggable={!readOnly}
                onDragStart={(ev) => startDrag(ev, { kind: 'entry', pdo: key, from: i }, drag, address ?? paddingName(e))}
                onDragEnd={() => {
                  drag.end();
                  setDropAt(null);
                }}
                onDragOver={over(i)}
                onDrop={drop(i)}
                data-testid={id(`entry-${i}`)}
                data-address={address ?? ''}
              >
                <td className="num mono muted">
                  {!readOnly && <span className="pdo-grip" aria-hidden="true">⋮⋮</span>}
                  {i + 1}
                </td>
                <td className="num mono">{off?.byte}</td>
                <td className="num mono">{off?.bit}</td>
                <td className="num mono">{e.bits}</td>
                <td className="mono nowrap" title={`mapping entry ${entryRawHex(e)}`}>
                  {address ?? <span className="muted">{hex(e.index)}</span>}
                </td>
                <td>
                  {address ? (d?.name ?? <span className="muted">unknown object</span>) : word ? word.name : <span className="muted">{paddingName(e)}</span>}
                  <ProblemList problems={eProblems} testid={id(`entry-${i}-problems`)} />
                </td>
                <td className="small mono">{d?.data_type ?? (typeof word?.data_type === 'string' ? word.data_type : '')}</td>
                <td className="small">{d?.unit ?? ''}</td>
                <td className="small nowrap">
                  {address ? (
                    <LiveCell live={props.live} address={address} rawUnit={props.rawUnits.get(address.toUpperCase()) ?? null} testid={`pdo-live-${pdo.name}-${address}`} />
                  ) : null}
                </td>
                {!readOnly && (
                  <td className="actions">
                    <button
                      type="button"
                      className="small-btn pdo-icon-btn"
                      disabled={i === 0}
                      onClick={() => props.onMove(i, i - 1)}
                      aria-label={`Move entry ${i + 1} of ${pdo.name} up`}
                      data-testid={id(`entry-${i}-up`)}
                    >
                      ↑
                    </button>
                    <button
                      type="button"
                      className="small-btn pdo-icon-btn"
                      disabled={i === pdo.entries.length - 1}
                      onClick={() => props.onMove(i, i + 2)}
                      aria-label={`Move entry ${i + 1} of ${pdo.name} down`}
                      data-testid={id(`entry-${i}-down`)}
                    >
                      ↓
                    </button>
                    <button
                      type="button"
                      className="small-btn pdo-icon-btn"
                      onClick={() => props.onRemove(i)}
                      aria-label={`Remove entry ${i + 1} (${address ?? paddingName(e)}) from ${pdo.name}`}
                      title="Remove"
                      data-testid={id(`entry-${i}-remove`)}
                    >
                      ✕
                    </button>
                  </td>
                )}
              </tr>
            );
          })}
          {!readOnly && (
            <tr
              className={`pdo-dropzone${rowDrop(pdo.entries.length)}`}
              onDragOver={over(pdo.entries.length)}
              onDrop={drop(pdo.entries.length)}
              data-testid={id('dropzone')}
            >
              <td colSpan={10} className="muted small">
                {pdo.entries.length === 0 ? 'No entries. ' : ''}Drop an object here (or between rows), or add one below.
              </td>
            </tr>
          )}
          {readOnly && pdo.entries.length === 0 && (
            <tr>
              <td colSpan={9} className="muted small">
                No entries.
              </td>
            </tr>
          )}
        </tbody>
      </table>
      {!readOnly && (
        <div className="pdo-add">
          <select value={pick} onChange={(e) => setPick(e.target.value)} aria-label={`Object to add to ${pdo.name}`} data-testid={id('add-select')}>
            <option value="">Add an object…</option>
            {addOptions.map((o) => (
              <option key={o.value} value={o.value}>
                {o.label}
              </option>
            ))}
          </select>
          <button
            type="button"
            disabled={!pick}
            data-testid={id('add')}
            onClick={() => {
              const o = addOptions.find((x) => x.value === pick);
              if (o) props.onAdd(o.entry);
            }}
          >
            Add
          </button>
        </div>
      )}
    </section>
  );
}
