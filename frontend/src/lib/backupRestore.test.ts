import { describe, expect, it } from 'vitest';
import type { Preflight, RestoreItem, RestoreReport } from '../api/types';
import { mergeProgressItem, parseBackupProgress, parseProgressItem } from './backupProgress';
import { canResume, mappedCount, nothingToWrite, reportVerdict, restoreBlocker, sortItems, statusLabel } from './backupRestore';

const OK: Preflight = { ok: true, problems: [], warnings: [], to_write: 3, unchanged: 10, read_only_skipped: 2, mapping: null, unreadable: [] };

function item(p: Partial<RestoreItem> & { address: string }): RestoreItem {
  return { name: '', status: 'written', old_raw_hex: null, new_raw_hex: null, code: null, code_hex: null, meaning: null, message: null, ...p };
}

function report(p: Partial<RestoreReport>): RestoreReport {
  return {
    id: 'r1',
    backup: 'b1',
    session: 's',
    time: '2025-11-21T15:04:09',
    dry_run: false,
    finished: true,
    stored: true,
    interrupted: false,
    pre_backup: 'b0',
    message: '',
    warnings: [],
    counts: { written: 2, would_write: 0, unchanged: 5, skipped: 1, failed: 0, pending: 0 },
    items: [],
    steps: [],
    unreadable: [],
    ...p,
  };
}

describe('nothingToWrite', () => {
  it('disables a restore of 0 entries, not its dry run', () => {
    expect(nothingToWrite({ ...OK, to_write: 0 }, false)).toMatch(/nothing to write/);
    expect(nothingToWrite({ ...OK, to_write: 0 }, true)).toBeNull();
    expect(nothingToWrite(OK, false)).toBeNull();
  });
});

describe('restoreBlocker', () => {
  it('needs a preflight, and a failed one blocks Restore', () => {
    expect(restoreBlocker(null, false)).toMatch(/preflight/);
    expect(restoreBlocker(OK, false)).toBeNull();
    const bad = { ...OK, ok: false, problems: [{ address: null, name: null, message: 'other drive', hint: 'h' }] };
    expect(restoreBlocker(bad, false)).toMatch(/a problem/);
  });
  it('asks for the name mapping opt-in for a backup of another family', () => {
    const mapped = { ...OK, mapping: [{ address: '0x2000:00', name: 'Speed', target: '0x6081:00', reason: null }, { address: '0x2001:00', name: 'X', target: null, reason: null }] };
    expect(restoreBlocker(mapped, false)).toMatch(/map entries by name/);
    expect(restoreBlocker(mapped, true)).toBeNull();
    // Before the opt-in the server sends no mapping (and a failed preflight): say what to do.
    const refused = { ...OK, ok: false, problems: [{ address: null, name: null, message: 'another drive family', hint: 'map by name' }] };
    expect(restoreBlocker(refused, false, true)).toMatch(/map entries by name/);
    expect(mappedCount(mapped.mapping)).toEqual({ mapped: 1, unmapped: 1 });
  });
});

describe('report', () => {
  it('says what happened', () => {
    expect(reportVerdict(report({})).kind).toBe('ok');
    expect(reportVerdict(report({ stored: false })).text).toMatch(/not stored/);
    expect(reportVerdict(report({ counts: { written: 1, would_write: 0, unchanged: 0, skipped: 0, failed: 1, pending: 0 }, stored: false })).kind).toBe('bad');
    const dry = report({ dry_run: true, stored: false, items: [item({ address: '0x1', status: 'would_write' })] });
    expect(reportVerdict(dry).text).toMatch(/Dry run: 1 entry would be written/);
  });
  it('offers Resume only for an interrupted real restore', () => {
    const cut = report({ interrupted: true, finished: false, counts: { written: 1, would_write: 0, unchanged: 0, skipped: 0, failed: 0, pending: 4 } });
    expect(canResume(cut)).toBe(true);
    expect(reportVerdict(cut).text).toMatch(/4 entries not yet written/);
    expect(canResume(report({}))).toBe(false);
    expect(canResume({ ...cut, dry_run: true })).toBe(false);
    expect(canResume(null)).toBe(false);
  });
  it('lists failures first', () => {
    const sorted = sortItems([item({ address: '0x2' }), item({ address: '0x3', status: 'unchanged' }), item({ address: '0x1', status: 'failed' })]);
    expect(sorted.map((i) => i.address)).toEqual(['0x1', '0x2', '0x3']);
    expect(statusLabel('skipped_read_only')).toBe('skipped (read-only)');
  });
});

describe('restore progress', () => {
  it('reads a restore progress frame with its item and restore id', () => {
    const m = parseBackupProgress(
      JSON.stringify({
        type: 'progress',
        session: 's',
        operation: 'restore',
        fraction: 1.5,
        message: 'writing',
        restore: 'r9',
        item: { address: '0x6081:00', status: 'failed', code_hex: '0x06090030', meaning: 'Value range exceeded' },
      }),
    );
    expect(m?.fraction).toBe(1);
    expect(m?.restoreId).toBe('r9');
    expect(m?.item).toEqual({ address: '0x6081:00', status: 'failed', code_hex: '0x06090030', meaning: 'Value range exceeded' });
    expect(parseBackupProgress('{"type":"state","session":"s"}')).toBeNull();
    expect(parseBackupProgress('not json')).toBeNull();
    expect(parseProgressItem('0x6040:00')).toEqual({ address: '0x6040:00' });
    expect(parseProgressItem({ status: 'written' })).toBeNull();
  });
  it('merges items in restore order, a later status winning', () => {
    let list = mergeProgressItem([], { address: '0x1', status: 'pending', why: 'entry' });
    list = mergeProgressItem(list, { address: '0x2', status: 'written' });
    list = mergeProgressItem(list, { address: '0x1', status: 'written', name: 'A' });
    expect(list.map((i) => [i.address, i.status, i.name, i.why])).toEqual([
      ['0x1', 'written', 'A', 'entry'],
      ['0x2', 'written', undefined, undefined],
    ]);
    // The server's restore progress names the step: address, name and why.
    expect(parseProgressItem({ address: '0x1600:01', name: 'RxPDO1 entry 1', why: 'pdo mapping' })).toEqual({ address: '0x1600:01', name: 'RxPDO1 entry 1', why: 'pdo mapping' });
  });
});
