import { describe, expect, it } from 'vitest';
import type { MappableObject, PdoLiveValue, PdoOut, PdoView } from '../../api/types';
import {
  type Draft,
  type DraftPdo,
  applyDrop,
  bitBudget,
  cobIdText,
  changedPdos,
  dataTypeName,
  decodeDrag,
  directionBudget,
  draftChanged,
  draftFromView,
  encodeDrag,
  entryOffsets,
  entryRawHex,
  filterMappable,
  formatLive,
  frameLength,
  groupProblems,
  inhibitMs,
  inhibitRaw,
  layoutFromDraft,
  moveItem,
  parseCobId,
  removeEntry,
  telegramBudget,
  transmissionChoice,
  transmissionFromChoice,
  transmissionOptions,
} from './pdoModel';

const SW = { index: 0x6041, subindex: 0, bits: 16 };
const POS = { index: 0x6064, subindex: 0, bits: 32 };
const VEL = { index: 0x606c, subindex: 0, bits: 32 };
const CW = { index: 0x6040, subindex: 0, bits: 16 };
const MODE = { index: 0x6060, subindex: 0, bits: 8 };

function pdo(direction: 'rx' | 'tx', number: number, entries: DraftPdo['entries'], enabled = true): DraftPdo {
  const base = direction === 'rx' ? 0x1600 : 0x1a00;
  return {
    direction,
    number,
    name: `${direction === 'rx' ? 'RPDO' : 'TPDO'}${number}`,
    mapping_index: base + number - 1,
    comm_index: base - 0x200 + number - 1,
    comm: { cob_id: 0x181, enabled, rtr_allowed: true, transmission_type: 255, inhibit_time: 0, event_timer: 0, sync_start: 0 },
    entries,
  };
}

function draft(): Draft {
  return {
    pdos: [pdo('rx', 1, [CW, MODE]), pdo('tx', 1, [SW]), pdo('tx', 2, [SW, POS])],
    assignment: null,
    telegram: null,
  };
}

describe('offsets', () => {
  it('places entries back to back, in bytes and bits', () => {
    const o = entryOffsets([SW, MODE, { index: 0x60fd, subindex: 0, bits: 1 }, { index: 0x60fe, subindex: 1, bits: 3 }, POS]);
    expect(o.map((x) => [x.offset_bits, x.byte, x.bit])).toEqual([
      [0, 0, 0],
      [16, 2, 0],
      [24, 3, 0],
      [25, 3, 1],
      [28, 3, 4],
    ]);
  });

  it('gives the raw mapping entry as CiA 301 writes it', () => {
    expect(entryRawHex(POS)).toBe('0x60640020');
    expect(entryRawHex({ index: 0, subindex: 0, bits: 16 })).toBe('0x00000010');
  });
});

describe('bit budget', () => {
  it('counts bits, bytes and entries against the limits', () => {
    const b = bitBudget([SW, POS], 64, 8);
    expect(b).toMatchObject({ bits: 48, bytes: 6, entries: 2, over: false, tooManyEntries: false });
    expect(b.fraction).toBeCloseTo(0.75);
    const over = bitBudget([SW, POS, VEL], 64, 2);
    expect(over).toMatchObject({ bits: 80, bytes: 10, over: true, tooManyEntries: true });
  });

  it('rounds a partial byte up', () => {
    expect(bitBudget([{ bits: 1 }], 64, 8).bytes).toBe(1);
  });

  it('sums the active PDOs of a direction against the family byte limit', () => {
    const d = draft();
    d.pdos.push(pdo('tx', 3, [POS, VEL], false));
    const b = directionBudget(d, 'tx', 'canopen', 8);
    // TPDO3 is disabled (COB-ID bit 31): not on the bus, not counted.
    expect(b).toMatchObject({ bytes: 8, over: false, pdos: ['TPDO1', 'TPDO2'] });
    expect(directionBudget(d, 'tx', 'canopen', 7).over).toBe(true);
  });

  it('counts only the assigned mapping objects on EtherCAT', () => {
    const d: Draft = { ...draft(), assignment: { rx: [0x1600], tx: [0x1a01] } };
    for (const p of d.pdos) p.comm = null;
    expect(directionBudget(d, 'tx', 'ethercat', 40)).toMatchObject({ bytes: 6, pdos: ['TPDO2'] });
  });

  it('says how many bytes a telegram still needs', () => {
    expect(telegramBudget(102, 384, [SW, POS])).toEqual({ telegram: 102, size: 48, bytes: 6, missing: 42 });
    expect(telegramBudget(103, 480, [SW, POS]).missing).toBe(54);
  });

  it('pads CAN FD frames to the next length, classic CAN not at all', () => {
    expect(frameLength(6, 'canopen')).toBe(6);
    expect(frameLength(9, 'canopen')).toBeNull();
    expect(frameLength(9, 'ethercat')).toBe(12);
    expect(frameLength(29, 'fixed')).toBe(32);
    expect(frameLength(48, 'telegram')).toBe(48);
    expect(frameLength(65, 'ethercat')).toBeNull();
  });
});

describe('drag and drop', () => {
  it('moves an item before the one it is dropped on', () => {
    expect(moveItem(['a', 'b', 'c', 'd'], 0, 2)).toEqual(['b', 'a', 'c', 'd']);
    expect(moveItem(['a', 'b', 'c', 'd'], 3, 0)).toEqual(['d', 'a', 'b', 'c']);
    expect(moveItem(['a', 'b', 'c', 'd'], 1, 4)).toEqual(['a', 'c', 'd', 'b']);
    // Dropped on itself or just after itself: nothing moves.
    expect(moveItem(['a', 'b', 'c'], 1, 1)).toEqual(['a', 'b', 'c']);
    expect(moveItem(['a', 'b', 'c'], 1, 2)).toEqual(['a', 'b', 'c']);
  });

  it('inserts a palette object at the drop place', () => {
    const d = applyDrop(draft(), { kind: 'object', direction: 'tx', entry: VEL }, { pdo: 'tx2', at: 1 });
    expect(d.pdos[2]?.entries).toEqual([SW, VEL, POS]);
    const end = applyDrop(draft(), { kind: 'object', direction: 'both', entry: VEL }, { pdo: 'tx1', at: 99 });
    expect(end.pdos[1]?.entries).toEqual([SW, VEL]);
  });

  it('refuses an object of the other direction', () => {
    const d0 = draft();
    const d = applyDrop(d0, { kind: 'object', direction: 'rx', entry: CW }, { pdo: 'tx1', at: 0 });
    expect(d).toBe(d0);
  });

  it('reorders within a PDO and moves between PDOs of the same direction', () => {
    const within = applyDrop(draft(), { kind: 'entry', pdo: 'tx2', from: 1 }, { pdo: 'tx2', at: 0 });
    expect(within.pdos[2]?.entries).toEqual([POS, SW]);
    const across = applyDrop(draft(), { kind: 'entry', pdo: 'tx2', from: 1 }, { pdo: 'tx1', at: 1 });
    expect(across.pdos[1]?.entries).toEqual([SW, POS]);
    expect(across.pdos[2]?.entries).toEqual([SW]);
    const d0 = draft();
    expect(applyDrop(d0, { kind: 'entry', pdo: 'rx1', from: 0 }, { pdo: 'tx1', at: 0 })).toBe(d0);
  });

  it('round-trips the drag payload and rejects anything else', () => {
    const item = { kind: 'object', direction: 'tx', entry: POS } as const;
    expect(decodeDrag(encodeDrag(item))).toEqual(item);
    expect(decodeDrag(encodeDrag({ kind: 'entry', pdo: 'tx1', from: 2 }))).toEqual({ kind: 'entry', pdo: 'tx1', from: 2 });
    expect(decodeDrag('hello')).toBeNull();
    expect(decodeDrag('{"kind":"object"}')).toBeNull();
  });

  it('removes an entry and tracks what changed', () => {
    const base = draft();
    const d = removeEntry(base, 'tx2', 0);
    expect(d.pdos[2]?.entries).toEqual([POS]);
    expect([...changedPdos(d, base)]).toEqual(['TPDO2']);
    expect(draftChanged(d, base)).toBe(true);
    expect(draftChanged(base, base)).toBe(false);
  });
});

describe('communication parameters', () => {
  it('maps CiA 301 transmission types to the select and back', () => {
    expect(transmissionChoice(0)).toBe('0');
    expect(transmissionChoice(1)).toBe('n');
    expect(transmissionChoice(240)).toBe('n');
    expect(transmissionChoice(245)).toBe('reserved');
    expect(transmissionChoice(253)).toBe('253');
    expect(transmissionFromChoice('n', 10)).toBe(10);
    expect(transmissionFromChoice('n', 255)).toBe(1);
    expect(transmissionFromChoice('254', 3)).toBe(254);
  });

  it('offers RTR-only types for TPDOs only', () => {
    expect(transmissionOptions('tx').map((o) => o.value)).toContain('252');
    expect(transmissionOptions('rx').map((o) => o.value)).not.toContain('252');
  });

  it('converts the inhibit time between ms and 100 µs', () => {
    expect(inhibitRaw(1.5)).toBe(15);
    expect(inhibitMs(15)).toBe(1.5);
  });

  it('reads and writes 11-bit COB-IDs in hex', () => {
    expect(parseCobId('0x281')).toBe(0x281);
    expect(parseCobId('281h')).toBe(0x281);
    expect(parseCobId('800')).toBeNull();
    expect(parseCobId('xyz')).toBeNull();
    expect(cobIdText(0x81)).toBe('0x081');
  });
});

describe('view and layout', () => {
  const out = (p: Partial<PdoOut> & Pick<PdoOut, 'direction' | 'number' | 'name'>): PdoOut => ({
    mapping_index: 0x1a00,
    comm_index: 0x1800,
    cob_id: 0x40000181,
    cob_id_hex: '0x181',
    enabled: true,
    rtr_allowed: false,
    transmission_type: 1,
    transmission_text: null,
    inhibit_time: 0,
    inhibit_time_ms: 0,
    event_timer: 0,
    sync_start: 0,
    active: true,
    bits: 16,
    max_bits: 64,
    bytes: 2,
    frame_length: 2,
    entries: [],
    ...p,
  });
  const view: PdoView = {
    kind: 'canopen',
    byte_order: 'little',
    rules: { max_entries: 8, max_bits: 64, max_bytes: null, mapping_state: 'preop', section: null, rpdo_count: 1, tpdo_count: 1, telegrams: [] },
    pdos: [
      out({ direction: 'tx', number: 1, name: 'TPDO1' }),
      out({ direction: 'rx', number: 1, name: 'RPDO1', comm_index: null, mapping_index: 0x1600 }),
    ],
    assignment: null,
    telegram: null,
    apply_unavailable: null,
    nmt_state: 'operational',
    problems: [],
  };

  it('puts RX first and keeps only the 11-bit identifier of the COB-ID', () => {
    const d = draftFromView(view);
    expect(d.pdos.map((p) => p.name)).toEqual(['RPDO1', 'TPDO1']);
    expect(d.pdos[1]?.comm?.cob_id).toBe(0x181);
    expect(d.pdos[0]?.comm).toBeNull();
  });

  it('sends communication parameters only where the family has them', () => {
    const layout = layoutFromDraft(draftFromView(view));
    expect(layout.pdos[0]).toEqual({ direction: 'rx', number: 1, entries: [] });
    expect(layout.pdos[1]).toMatchObject({ cob_id: 0x181, enabled: true, rtr_allowed: false, transmission_type: 1 });
    expect(layout).not.toHaveProperty('telegram');
  });
});

describe('problems', () => {
  it('puts each problem next to its entry, field, PDO or above the tables', () => {
    const g = groupProblems(
      [
        { message: 'too long', pdo: 'TPDO1', entry: null, field: 'entries', section: null },
        { message: 'not mappable', pdo: 'TPDO1', entry: 2, field: 'entries', section: null },
        { message: 'bad id', pdo: 'TPDO1', entry: null, field: 'cob_id', section: null },
        { message: 'over 40 bytes', pdo: null, entry: null, field: 'assignment', section: '000 §2.2' },
        { message: 'unknown pdo', pdo: 'TPDO9', entry: null, field: null, section: null },
      ],
      new Set(['TPDO1']),
    );
    const t = g.byPdo.get('TPDO1');
    expect(t?.pdo.map((p) => p.message)).toEqual(['too long']);
    expect(t?.entries.get(2)?.[0]?.message).toBe('not mappable');
    expect(t?.fields.get('cob_id')?.[0]?.message).toBe('bad id');
    expect(g.general.map((p) => p.message)).toEqual(['over 40 bytes', 'unknown pdo']);
    expect(g.count).toBe(5);
  });
});

describe('live values and palette', () => {
  // A value as the server sends it (services/cyclic.py values_view).
  const live = (v: Pick<PdoLiveValue, 'value' | 'engineering' | 'unit'> & Partial<PdoLiveValue>): PdoLiveValue => ({
    raw_unit: null,
    pdo: 'TPDO1',
    age_s: 0.01,
    stale: false,
    ...v,
  });

  it('shows raw and engineering values, each with its unit', () => {
    expect(formatLive(live({ value: 12345, engineering: 0.0942, unit: 'rev', pdo: 'TPDO2' }), 'inc')).toEqual({
      raw: '12345 inc',
      eng: '0.0942 rev',
    });
    // At zero the numbers agree, the units do not: still both.
    expect(formatLive(live({ value: 0, engineering: 0, unit: 'deg', raw_unit: 'inc' }), null)).toEqual({ raw: '0 inc', eng: '0 deg' });
    expect(formatLive(live({ value: 25, engineering: 2.5, unit: '%', raw_unit: '0.1 %', pdo: 'RPDO4' }), null).raw).toBe('25 × 0.1 %');
    // Unscaled: one number.
    expect(formatLive(live({ value: 0x237, engineering: 0x237, unit: null }), null)).toEqual({ raw: '567', eng: null });
    expect(formatLive(live({ value: 8, engineering: 8, unit: 'mode' }), null)).toEqual({ raw: '8 mode', eng: null });
  });

  it('names data types the server sends as CiA 306 numbers', () => {
    expect(dataTypeName(4)).toBe('INTEGER32');
    expect(dataTypeName(0x1b)).toBe('UNSIGNED64');
    expect(dataTypeName('UNSIGNED16')).toBe('UNSIGNED16');
    expect(dataTypeName(0x99)).toBe('type 0x0099');
    expect(dataTypeName(null)).toBeNull();
  });

  it('filters by address, hex index, name and type', () => {
    const list: MappableObject[] = [
      { address: '0x6064:00', index: 0x6064, subindex: 0, name: 'Position actual value', data_type: 'INTEGER32', bits: 32, unit: 'inc', direction: 'tx' },
      { address: '0x606C:00', index: 0x606c, subindex: 0, name: 'Velocity actual value', data_type: 'INTEGER32', bits: 32, unit: 'inc/s', direction: 'tx' },
    ];
    expect(filterMappable(list, '6064').map((o) => o.index)).toEqual([0x6064]);
    expect(filterMappable(list, '606Ch').map((o) => o.index)).toEqual([0x606c]);
    expect(filterMappable(list, 'actual velocity').map((o) => o.index)).toEqual([0x606c]);
    expect(filterMappable(list, '').length).toBe(2);
  });
});
