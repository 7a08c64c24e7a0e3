import { describe, expect, it } from 'vitest';
import type { SessionInfo } from '../api/types';
import { busLabel, driveTree, treeAlarm, treeControl } from './driveTree';

const identity = { vendor_id: 1, product_code: 2, revision: 3, serial: null, device_name: '', hardware_version: null, software_version: null };

function session(id: string, over: Partial<SessionInfo>): SessionInfo {
  return {
    id,
    bitrate: null,
    channel: 'sim0',
    connected: true,
    dirty: [],
    encoder: { counts_per_rev: null, source: '', rescaled: false },
    fieldbus: 'canopen',
    identity,
    interface: 'virtual',
    link: 'canopen',
    nmt_state: 'operational',
    node_id: 1,
    note: null,
    profile_id: 'cia402-generic',
    profile_name: 'Generic CiA 402',
    simulated: true,
    state: 'Switch on disabled',
    ...over,
  } as SessionInfo;
}

const twins = [
  session('lecsn-t-1', { fieldbus: 'profinet', interface: 'profinet', channel: '127.0.0.1:34964', profile_name: 'LECSN-T', identity: { ...identity, device_name: 'LECSN2-T5' } }),
  session('smartris-3', { node_id: 3, profile_name: 'smartris' }),
  session('ctmm04x-2', { fieldbus: 'cclink-ie-tsn', interface: 'slmp', channel: '127.0.0.1:5010', node_id: 2, profile_name: 'CTMM04x' }),
  session('hiwin-e-2', { fieldbus: 'ethercat', interface: 'ethercat', channel: 'eth1', node_id: 2, profile_name: 'HIWIN E' }),
  session('cia402-generic-1', { node_id: 1 }),
  session('ctmm04x-1', { fieldbus: 'cclink-ie-tsn', interface: 'slmp', channel: '127.0.0.1:5010', node_id: 1, profile_name: 'CTMM04x', state: 'Fault' }),
];

describe('busLabel', () => {
  it('names the fieldbus and where it is, the interface only where the fieldbus does not imply it', () => {
    expect(busLabel({ fieldbus: 'canopen', interface: 'virtual', channel: 'sim0' })).toBe('CANopen · virtual:sim0');
    expect(busLabel({ fieldbus: 'ethercat', interface: 'ethercat', channel: 'eth1' })).toBe('EtherCAT · eth1');
    expect(busLabel({ fieldbus: 'cclink-ie-tsn', interface: 'slmp', channel: '127.0.0.1:5010' })).toBe('CC-Link IE TSN · SLMP 127.0.0.1:5010');
    expect(busLabel({ fieldbus: 'profinet', interface: 'profinet', channel: '192.168.0.10' })).toBe('PROFINET · 192.168.0.10');
    // A CANopen profile on a real CAN interface, and a fieldbus id the UI does not know.
    expect(busLabel({ fieldbus: 'canopen', interface: 'socketcan', channel: 'can0' })).toBe('CANopen · socketcan:can0');
    expect(busLabel({ fieldbus: 'sercos', interface: 'x', channel: 'y' })).toBe('sercos · x:y');
  });
});

describe('driveTree', () => {
  const tree = driveTree(twins);

  it('groups the sessions by bus, whatever order the server sent them in', () => {
    expect(tree.map((b) => b.label)).toEqual([
      'CANopen · virtual:sim0',
      'CC-Link IE TSN · SLMP 127.0.0.1:5010',
      'EtherCAT · eth1',
      'PROFINET · 127.0.0.1:34964',
    ]);
    expect(driveTree([...twins].reverse())).toEqual(tree);
  });

  it('makes each CANopen node a drive of one axis, sorted by node, named as the header names it', () => {
    const can = tree[0]!;
    expect(can.drives.map((d) => [d.name, d.label, d.axes.length])).toEqual([
      ['Generic CiA 402', 'node 1', 1],
      ['smartris', 'node 3', 1],
    ]);
    // The device's own name wins over the profile's (as DriveTitle).
    expect(tree[3]!.drives[0]!.name).toBe('LECSN2-T5');
    expect(tree[2]!.drives[0]!.label).toBe('slave 2');
  });

  it('puts the axes of one SLMP station under one drive, X before Y', () => {
    const slmp = tree[1]!;
    expect(slmp.drives).toHaveLength(1);
    const drive = slmp.drives[0]!;
    expect(drive.label).toBe('2 axes');
    expect(drive.axes.map((a) => [a.session.id, a.label])).toEqual([
      ['ctmm04x-1', 'axis X'],
      ['ctmm04x-2', 'axis Y'],
    ]);
    // A folded bus still says that one of its axes is in Fault.
    expect(slmp.faults).toBe(1);
    expect(tree[0]!.faults).toBe(0);
  });

  it('is empty without sessions', () => {
    expect(driveTree([])).toEqual([]);
  });
});

describe('treeAlarm', () => {
  const following = { table: 'error_code', code: 0x8611, code_hex: '0x8611', display: 'AL.42', name: 'Following error', kind: 'fault', cause: 'position deviation too large', remedy: null, section: null };

  it('shows the live alarm of a subscribed drive with its display code, name and cause', () => {
    const a = treeAlarm('Fault', { state: 'Fault', error: following, error_code: 0x8611 }, true);
    expect(a).toEqual({ text: 'AL.42', title: 'AL.42 Following error: position deviation too large', kind: 'fault', live: true });
  });

  it('shows a warning (a code without Fault) in amber, and no alarm for a "no error" entry', () => {
    const warn = { ...following, kind: 'warning', display: null, code_hex: '0xFF01', name: 'Overload warning', cause: null };
    expect(treeAlarm('Operation enabled', { state: 'Operation enabled', error: warn, error_code: 0xff01 }, true)).toMatchObject({ text: '0xFF01', kind: 'warning' });
    const none = { ...following, kind: 'info', code: 0, code_hex: '0x0000', name: 'No error' };
    expect(treeAlarm('Operation enabled', { state: 'Operation enabled', error: none, error_code: 0 }, true)).toBeNull();
  });

  it('says FAULT without a code for a drive nobody subscribed to, and ignores a stale live state', () => {
    expect(treeAlarm('Fault', null, false)).toMatchObject({ text: 'FAULT', kind: 'fault', live: false });
    // The drive was reset since the page that read its alarm closed: the list's state wins.
    expect(treeAlarm('Switch on disabled', { state: 'Fault', error: following, error_code: 0x8611 }, true)).toBeNull();
    // The same state but not fresh (no longer subscribed): the code is not claimed.
    expect(treeAlarm('Operation enabled', { state: 'Operation enabled', error: following, error_code: 0x8611 }, false)).toBeNull();
    expect(treeAlarm('Switch on disabled', null, false)).toBeNull();
  });
});

describe('treeControl', () => {
  it('says who holds control in the header indicator\'s words', () => {
    expect(treeControl({ known: false, owner: null, user: null, you: false }, 'local').who).toBe('unknown');
    expect(treeControl({ known: true, owner: null, user: null, you: false }, 'local')).toMatchObject({ text: 'nobody', who: 'nobody' });
    expect(treeControl({ known: true, owner: 'ui-1', user: 'local', you: true }, 'local')).toMatchObject({ text: 'you', who: 'you' });
    expect(treeControl({ known: true, owner: 'ui-2', user: 'local', you: false }, 'local')).toMatchObject({ text: 'you (ui-2)', who: 'you' });
    expect(treeControl({ known: true, owner: 'ui-3', user: 'alice', you: false }, 'bob')).toMatchObject({ text: 'alice (ui-3)', who: 'other' });
    expect(treeControl({ known: true, owner: 'script-7', user: null, you: false }, null)).toMatchObject({ text: 'script-7', who: 'other' });
  });
});
