import { describe, expect, it } from 'vitest';
import type { NetworkLedInfo, ObjectInfo, ProfileDetail } from '../api/types';
import { ledGroups, networkAddresses, networkRows, nodeLabel, slmpAxis, slmpAxisLabel } from './network';

function obj(address: string, access = 'ro'): ObjectInfo {
  const [idx, sub] = address.slice(2).split(':');
  return {
    index: Number.parseInt(idx ?? '0', 16),
    subindex: Number.parseInt(sub ?? '0', 16),
    address,
    name: address,
    name_local: null,
    data_type: 'UNSIGNED16',
    access,
    pdo_mapping: 'none',
    default: null,
    min: null,
    max: null,
    unit: null,
    scale: 1,
    raw_unit: null,
    group: null,
    persist: false,
    process: false,
    description: null,
    section: null,
    values: null,
    pnu: null,
    symbol: null,
  };
}

function led(name: string, state: string): NetworkLedInfo {
  return { led: name, state, meaning: `${name} ${state}`, section: 's' };
}

describe('slmpAxis', () => {
  it('names the axis of node id axis + 1 (003 §4-2)', () => {
    expect([1, 2, 3, 4].map(slmpAxis)).toEqual(['X', 'Y', 'Z', 'U']);
    expect(slmpAxis(0)).toBeNull();
    expect(slmpAxis(5)).toBeNull();
    expect(slmpAxis(1.5)).toBeNull();
    expect(slmpAxisLabel(1)).toBe('X (node id 1, multidrop 0)');
    expect(slmpAxisLabel(9)).toBe('no axis (node id 9)');
  });
});

describe('networkRows', () => {
  const profile: Pick<ProfileDetail, 'object_list' | 'network'> = {
    object_list: [obj('0x1017:00', 'rw'), obj('0x039A:00'), obj('0x1010:01', 'wo')],
    network: {
      summary: 's',
      section: 's',
      objects: [
        { address: '0x039a:00', note: 'telegram', section: '004' },
        { address: '0x1017:00', note: 'heartbeat', section: '301' },
        { address: '0x1010:01', note: 'write-only', section: '301' },
        { address: '0x2000:00', note: 'missing', section: '?' },
      ],
      addressing: [],
      leds: [],
    },
  };

  it('joins the network objects with the profile, in the section order', () => {
    const rows = networkRows(profile);
    expect(rows.map((r) => r.entry.note)).toEqual(['telegram', 'heartbeat', 'write-only', 'missing']);
    expect(rows[0]?.object?.address).toBe('0x039A:00');
    expect(rows[3]?.object).toBeNull();
  });

  it('reads only what the drive can be asked for', () => {
    expect(networkAddresses(networkRows(profile))).toEqual(['0x039A:00', '0x1017:00']);
  });

  it('has no rows without a network section', () => {
    expect(networkRows({ object_list: profile.object_list, network: null })).toEqual([]);
    expect(networkRows({ object_list: profile.object_list })).toEqual([]);
  });
});

describe('ledGroups', () => {
  it("keeps one LED's states together, LEDs in first-named order", () => {
    const g = ledGroups([led('NS', 'off'), led('MS', 'off'), led('NS', 'green on')]);
    expect(g.map((x) => x.led)).toEqual(['NS', 'MS']);
    expect(g[0]?.states.map((s) => s.state)).toEqual(['off', 'green on']);
  });
});

describe('nodeLabel', () => {
  it("names the node as the session's fieldbus does", () => {
    expect(nodeLabel('slmp', 2)).toBe('axis Y');
    expect(nodeLabel('slmp', 9)).toBe('axis ? (node id 9)');
    expect(nodeLabel('profinet', 1)).toBe('DO-ID 1');
    expect(nodeLabel('ethercat', 3)).toBe('slave 3');
    expect(nodeLabel('virtual', 5)).toBe('node 5');
    expect(nodeLabel('socketcan', 12)).toBe('node 12');
  });
});
