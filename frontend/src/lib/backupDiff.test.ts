import { describe, expect, it } from 'vitest';
import type { BackupInfo, Difference, GroupInfo } from '../api/types';
import { addressOrder, diffCounts, groupDifferences, isEqual, kindLabel, sideCell, sourceFromKey, sourceKey, sourceLabel } from './backupDiff';

function diff(p: Partial<Difference> & { address: string }): Difference {
  return {
    name: '',
    group: null,
    unit: null,
    raw_unit: null,
    a_value: null,
    b_value: null,
    a_raw_hex: null,
    b_raw_hex: null,
    a_engineering: null,
    b_engineering: null,
    kind: 'changed',
    ...p,
  };
}

const GROUPS: GroupInfo[] = [
  { id: 'identity', name: 'Identity', name_local: null, description: null },
  { id: 'position', name: 'Position', name_local: null, description: null },
  { id: 'velocity', name: 'Velocity', name_local: null, description: null },
];

const BACKUP = { id: 'b1', label: 'after tuning', time: '2025-11-21T15:04:09' } as BackupInfo;

describe('sources', () => {
  it('round-trips every kind through a select value', () => {
    for (const s of [
      { kind: 'drive', session: 's1' },
      { kind: 'defaults', profile: 'p' },
      { kind: 'backup', id: 'b1' },
    ] as const) {
      expect(sourceFromKey(sourceKey(s), 's1', 'p')).toEqual(s);
    }
    expect(sourceFromKey('backup:', 's1', 'p')).toBeNull();
    expect(sourceFromKey('nonsense', 's1', 'p')).toBeNull();
  });
  it('names the sources in words', () => {
    expect(sourceLabel('drive', [])).toBe('Live drive');
    expect(sourceLabel('defaults', [])).toBe('Profile defaults');
    expect(sourceLabel('backup:b1', [BACKUP])).toMatch(/^Backup: “after tuning” · 2025-11-21 /);
    expect(sourceLabel('backup:gone', [])).toBe('Backup gone');
  });
});

describe('groupDifferences', () => {
  const c = {
    differences: [
      diff({ address: '0x6081:00', group: 'position', kind: 'changed' }),
      diff({ address: '0x6065:00', group: 'position', kind: 'only_a' }),
      diff({ address: '0x1018:01', group: 'identity', kind: 'same' }),
      diff({ address: '0x2000:00', group: null, kind: 'only_b' }),
      diff({ address: '0x3000:00', group: 'vendor', kind: 'changed' }),
      diff({ address: '0x60FF:00', group: 'Velocity', kind: 'changed' }),
    ],
  };
  it('keeps the profile group order, unknown groups after, ungrouped last; rows by address', () => {
    const g = groupDifferences(c, GROUPS, false);
    expect(g.map((x) => x.name)).toEqual(['Position', 'Velocity', 'vendor', 'Not in a group']);
    expect(g[0]?.rows.map((r) => r.address)).toEqual(['0x6065:00', '0x6081:00']);
  });
  it('shows equal entries only with "show all"', () => {
    expect(groupDifferences(c, GROUPS, false).some((x) => x.id === 'identity')).toBe(false);
    const all = groupDifferences(c, GROUPS, true);
    expect(all[0]?.name).toBe('Identity');
    expect(all[0]?.differences).toBe(0);
  });
});

describe('counts and equality', () => {
  it('counts each kind and trusts both the flag and the rows', () => {
    const c = { equal: false, same: 7, differences: [diff({ address: '0x1', kind: 'changed' }), diff({ address: '0x2', kind: 'only_b' })] };
    expect(diffCounts(c)).toEqual({ changed: 1, onlyA: 0, onlyB: 1, same: 7 });
    expect(isEqual(c)).toBe(false);
    expect(isEqual({ equal: false, differences: [diff({ address: '0x1', kind: 'same' })] })).toBe(true);
    expect(isEqual({ equal: true, differences: [] })).toBe(true);
  });
  it('labels the kinds', () => {
    expect(kindLabel('only_a')).toBe('only in A');
    expect(kindLabel('only_b')).toBe('only in B');
    expect(kindLabel('same')).toBe('equal');
  });
  it('orders addresses by index then subindex', () => {
    expect(addressOrder('0x6081:00')).toBeLessThan(addressOrder('0x6081:01'));
    expect(addressOrder('0x1018:04')).toBeLessThan(addressOrder('0x6040:00'));
    expect(addressOrder('P24641')).toBe(Number.MAX_SAFE_INTEGER);
  });
});

describe('sideCell', () => {
  const row = diff({
    address: '0x6081:00',
    unit: 'rpm',
    raw_unit: 'inc/s',
    a_value: 200000,
    b_value: 1000,
    a_raw_hex: '400d0300',
    b_raw_hex: 'e8030000',
    a_engineering: 91.552734375,
    b_engineering: 0.457763671875,
  });
  it('shows engineering value with unit and the raw bytes in bus order', () => {
    expect(sideCell(row, 'a')).toEqual({ value: '91.553 rpm', raw: '40 0D 03 00', absent: false });
    expect(sideCell(row, 'b')).toEqual({ value: '0.4578 rpm', raw: 'E8 03 00 00', absent: false });
  });
  it('falls back to the value with its raw unit when there is no engineering unit', () => {
    const r = diff({ address: '0x6060:00', raw_unit: 'inc', a_value: 3, a_raw_hex: '03' });
    expect(sideCell(r, 'a').value).toBe('3 inc');
    expect(sideCell(diff({ address: '0x1008:00', a_value: 'SIM' }), 'a').value).toBe('SIM');
  });
  it('marks the side that lacks the entry', () => {
    const r = diff({ address: '0x2000:00', kind: 'only_a', a_value: 1, a_raw_hex: '01' });
    expect(sideCell(r, 'b')).toEqual({ value: '—', raw: '—', absent: true });
    expect(sideCell(r, 'a').absent).toBe(false);
  });
});
