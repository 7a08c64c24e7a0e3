import { describe, expect, it } from 'vitest';
import type { ObjectInfo } from '../api/types';
import { NO_FILTER, buildSearchIndex, canonicalAddress, differsFromDefault, filterObjects, groupObjects, isParameter } from './dictionary';

function obj(p: Partial<ObjectInfo>): ObjectInfo {
  return {
    index: 0x6040, subindex: 0, address: '0x6040:00', name: 'Controlword', name_local: null, data_type: 'UNSIGNED16',
    access: 'rw', pdo_mapping: 'rx', default: 0, min: null, max: null, unit: null, scale: 1, raw_unit: null,
    group: 'g1', persist: false, process: true, description: null, section: null, values: null, pnu: null, symbol: null, ...p,
  };
}

const OBJECTS = [
  obj({}),
  obj({ index: 0x6083, address: '0x6083:00', name: 'Profile acceleration', pnu: 24707, process: false, pdo_mapping: 'none', group: 'g2' }),
  obj({ index: 0x2001, address: '0x2001:00', name: 'Operation mode', name_local: '動作モード', symbol: 'PA01', pnu: 8193, process: false, group: 'g2' }),
  obj({ index: 0x6041, address: '0x6041:00', name: 'Statusword', access: 'ro', pdo_mapping: 'tx', description: 'CiA 402 status bits' }),
  obj({ index: 0x2460, address: '0x2460:00', name: 'Something', pnu: 9312, process: false }),
];
const INDEX = buildSearchIndex(OBJECTS);
const find = (query: string) => filterObjects(OBJECTS, INDEX, { ...NO_FILTER, query }).map((i) => OBJECTS[i]?.address);

describe('search', () => {
  it('takes an index as manuals write it', () => {
    for (const q of ['6040', '0x6040', '6040h', '6040H', 'P24640', '0x6040:00', '6040h.0']) expect(find(q)).toContain('0x6040:00');
    expect(find('6040h')).toEqual(['0x6040:00']);
  });
  it('matches a PNU exactly, a prefix while typing', () => {
    expect(find('P24707')).toEqual(['0x6083:00']);
    expect(find('P2470')).toEqual(['0x6083:00']);
    expect(find('P8193')).toEqual(['0x2001:00']);
  });
  it('matches name, local name, symbol and description, all words', () => {
    expect(find('profile accel')).toEqual(['0x6083:00']);
    expect(find('動作')).toEqual(['0x2001:00']);
    expect(find('pa01')).toEqual(['0x2001:00']);
    expect(find('status bits')).toEqual(['0x6041:00']);
    expect(find('profile status')).toEqual([]);
  });
  it('filters by access, PDO and group', () => {
    const f = (p: Partial<typeof NO_FILTER>) => filterObjects(OBJECTS, INDEX, { ...NO_FILTER, ...p }).length;
    expect(f({ access: 'writable' })).toBe(4);
    expect(f({ access: 'readable' })).toBe(5);
    expect(f({ pdo: true })).toBe(4);
    expect(f({ group: 'g2' })).toBe(2);
  });
  it('differs-from-default needs a live value', () => {
    const live = new Map([['0x6083:00', 5]]);
    const rows = filterObjects(OBJECTS, INDEX, { ...NO_FILTER, differs: true }, (o) => live.get(o.address));
    expect(rows.map((i) => OBJECTS[i]?.address)).toEqual(['0x6083:00']);
    expect(differsFromDefault(obj({ default: 1 }), true)).toBe(false);
    expect(differsFromDefault(obj({ default: null }), 3)).toBeNull();
  });
});

describe('parameters', () => {
  it('are writable non-process objects, grouped in profile order', () => {
    const params = OBJECTS.filter(isParameter);
    const groups = groupObjects({ groups: [{ id: 'g2', name: 'Two', name_local: null, description: null }, { id: 'g1', name: 'One', name_local: null, description: null }] }, params);
    expect(groups.map((g) => g.group.id)).toEqual(['g2', 'g1']);
    expect(groups[0]?.objects.map((o) => o.address)).toEqual(['0x6083:00', '0x2001:00']);
  });
  it('normalises dirty addresses', () => {
    expect(canonicalAddress('0x6081:00')).toBe('0x6081:00');
    expect(canonicalAddress('0x6081')).toBe('0x6081:00');
    expect(canonicalAddress('0x607a:1')).toBe('0x607A:01');
  });
});
