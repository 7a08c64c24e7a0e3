import { describe, expect, it } from 'vitest';
import type { BackupInfo } from '../api/types';
import { alarmText, backupCompleteness, controlCell, lastBackup, placeKey, protectionText } from './axes';

const identity = { vendor_id: 1, product_code: 2, revision: 3, serial: 44, device_name: 'X', hardware_version: null, software_version: null };
const session = { identity, profile_id: 'cia402-generic', interface: 'virtual', channel: 'sim', node_id: 1 };

function backup(id: string, time: string, over: Partial<BackupInfo> = {}): BackupInfo {
  return {
    id,
    time,
    label: '',
    note: '',
    profile_id: 'cia402-generic',
    profile_version: '1',
    drive_key: '00000001-00000002-44',
    identity,
    firmware: null,
    bus: {},
    entries: 10,
    file: `${id}.json`,
    sha256: '',
    unreadable: [],
    queued: false,
    complete: true,
    source: 'drive',
    ...over,
  };
}

describe('lastBackup', () => {
  it('picks the newest backup of the same drive, whatever the list order', () => {
    const list = [backup('a', '2026-12-07T08:00:00Z'), backup('c', '2026-12-07T10:00:00Z'), backup('b', '2026-12-07T09:00:00Z')];
    expect(lastBackup(session, list)?.id).toBe('c');
  });
  it('ignores backups of other drives (another serial) and matches a drive without serial by its place', () => {
    const other = backup('o', '2026-12-08T00:00:00Z', { identity: { ...identity, serial: 45 }, drive_key: 'x' });
    expect(lastBackup(session, [other])).toBeNull();
    const noSerial = { ...session, identity: { ...identity, serial: null } };
    const byPlace = backup('p', '2026-12-07T00:00:00Z', { identity: { ...identity, serial: null }, drive_key: placeKey(noSerial) });
    expect(lastBackup(noSerial, [other, byPlace])?.id).toBe('p');
  });
});

describe('cells', () => {
  it('says whether a backup is complete and how many entries it lacks', () => {
    expect(backupCompleteness({ complete: true, unreadable: [] })).toBe('complete');
    expect(backupCompleteness({ complete: false, unreadable: [{}, {}] as never })).toBe('incomplete · 2 unreadable');
  });
  it('names the active alarm by the profile, else by its code, else none', () => {
    expect(alarmText(null)).toBeNull();
    expect(alarmText({ error: null, error_code: 0 })).toBeNull();
    expect(alarmText({ error: null, error_code: 0x8611 })).toBe('0x8611');
    expect(
      alarmText({ error: { table: 'error_code', code: 0x8611, code_hex: '0x8611', display: null, name: 'Following error', kind: 'fault', cause: null, remedy: null, section: null }, error_code: 0x8611 }),
    ).toBe('0x8611 Following error');
  });
  it('marks the axes STOP ALL stops: held by this tab or another tab of the same account', () => {
    expect(controlCell({ owner: null, user: null, you: false }, 'local')).toEqual({ text: 'nobody', stoppedByStopAll: false });
    expect(controlCell({ owner: 'ui-1', user: 'local', you: true }, 'local')).toEqual({ text: 'you (this tab)', stoppedByStopAll: true });
    expect(controlCell({ owner: 'ui-2', user: 'local', you: false }, 'local')).toEqual({ text: 'you (ui-2)', stoppedByStopAll: true });
    expect(controlCell({ owner: 'ui-3', user: 'bob', you: false }, 'eve')).toEqual({ text: 'bob (ui-3)', stoppedByStopAll: false });
  });
  it('sums the protection up', () => {
    expect(protectionText(null)).toBe('—');
    expect(protectionText({ deadman_ms: 250, stop_path: 'dead-man thread', drive_watchdog: null, summary: '' })).toBe('dead-man thread · 250 ms · no drive watchdog');
  });
});
