import { describe, expect, it } from 'vitest';
import type { BackupInfo, Identity } from '../api/types';
import { backupTitle, downloadName, driveKeyOf, formatTime, sameDrive, toDate, uploadProblem } from './backupHistory';

const ID: Identity = {
  vendor_id: 1396986699,
  product_code: 1026,
  revision: 65536,
  serial: 1,
  device_name: 'sim',
  hardware_version: null,
  software_version: null,
};

function backup(p: Partial<BackupInfo>): BackupInfo {
  return {
    id: 'b',
    time: '2025-11-21T15:04:09',
    label: '',
    note: '',
    profile_id: 'cia402-generic',
    profile_version: '1',
    drive_key: 'k',
    identity: ID,
    firmware: null,
    bus: {},
    entries: 1,
    file: 'f',
    sha256: '',
    unreadable: [],
    queued: false,
    complete: true,
    source: 'drive',
    ...p,
  };
}

describe('sameDrive / driveKeyOf', () => {
  it('matches vendor, product code and serial; another vendor with serial 1 is another drive', () => {
    expect(sameDrive(ID, { ...ID, revision: 2 })).toBe(true);
    expect(sameDrive(ID, { ...ID, vendor_id: 43690 })).toBe(false);
    expect(sameDrive(ID, { ...ID, serial: null })).toBe(false);
  });
  it('uses the session key when the server sends one, else a backup of the same drive', () => {
    const list = [backup({ drive_key: 'other', identity: { ...ID, serial: 9 } }), backup({ drive_key: 'mine' })];
    expect(driveKeyOf({ identity: ID, drive_key: 'server' }, list)).toBe('server');
    expect(driveKeyOf({ identity: ID }, list)).toBe('mine');
    expect(driveKeyOf({ identity: { ...ID, serial: 5 } }, list)).toBeNull();
    expect(driveKeyOf(null, list)).toBeNull();
  });
});

describe('times and names', () => {
  it('reads ISO text and epoch seconds alike', () => {
    expect(toDate('2025-11-21T15:04:09')?.getMinutes()).toBe(4);
    expect(toDate(1_700_000_000)?.getTime()).toBe(1_700_000_000_000);
    expect(toDate('not a time')).toBeNull();
    expect(formatTime('2025-11-21T15:04:09')).toBe('2025-11-21 15:04:09');
    expect(formatTime('garbage')).toBe('garbage');
  });
  it('names a backup by its label, else by its time', () => {
    expect(backupTitle(backup({ label: ' after tuning ' }))).toBe('“after tuning” · 2025-11-21 15:04:09');
    expect(backupTitle(backup({}))).toBe('2025-11-21 15:04:09');
  });
  it('makes a safe download name', () => {
    expect(downloadName(backup({ label: 'After tuning / axis 2' }), 'dcf')).toBe('cia402-generic-after-tuning-axis-2.dcf');
    expect(downloadName(backup({ id: 'abc' }), 'json')).toBe('cia402-generic-abc.json');
  });
  it('takes JSON and DCF files only', () => {
    expect(uploadProblem('x.json', 10)).toBeNull();
    expect(uploadProblem('X.DCF', 10)).toBeNull();
    expect(uploadProblem('x.csv', 10)).toMatch(/neither/);
    expect(uploadProblem('x.json', 0)).toMatch(/empty/);
  });
});
