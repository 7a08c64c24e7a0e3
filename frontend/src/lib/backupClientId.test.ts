import { describe, expect, it } from 'vitest';
import { CLIENT_ID_KEY, type IdStorage, isValidClientId, makeClientId, tabClientId } from './backupClientId';

function memStorage(init: Record<string, string> = {}): IdStorage & { data: Record<string, string> } {
  const data = { ...init };
  return { data, getItem: (k) => data[k] ?? null, setItem: (k, v) => void (data[k] = v) };
}

describe('makeClientId', () => {
  it('is "ui-" and 12 hex digits from the random bytes', () => {
    expect(makeClientId(() => new Uint8Array([0x3f, 0x2a, 0x00, 0xff, 0x10, 0x01]))).toBe('ui-3f2a00ff1001');
  });
  it('differs between calls with the real random source', () => {
    const a = makeClientId();
    expect(a).toMatch(/^ui-[0-9a-f]{12}$/);
    expect(makeClientId()).not.toBe(a);
  });
});

describe('tabClientId', () => {
  it('makes an id once per tab and keeps it in the tab storage', () => {
    const s = memStorage();
    let n = 0;
    const make = () => `ui-${++n}`;
    expect(tabClientId(s, make)).toBe('ui-1');
    expect(s.data[CLIENT_ID_KEY]).toBe('ui-1');
    // A reload of the same tab (same storage) keeps the id.
    expect(tabClientId(s, make)).toBe('ui-1');
    // Another tab (its own storage) gets its own.
    expect(tabClientId(memStorage(), make)).toBe('ui-2');
  });
  it('replaces a stored value that cannot be a header value', () => {
    const s = memStorage({ [CLIENT_ID_KEY]: 'bad id\n' });
    expect(tabClientId(s, () => 'ui-new')).toBe('ui-new');
    expect(isValidClientId('ui-3f2a')).toBe(true);
    expect(isValidClientId('')).toBe(false);
    expect(isValidClientId('é')).toBe(false);
  });
  it('still gives one id per page load without storage', () => {
    const id = tabClientId(null, () => 'ui-mem');
    expect(tabClientId(null, () => 'ui-other')).toBe(id);
  });
});
