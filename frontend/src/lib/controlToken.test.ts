import { describe, expect, it } from 'vitest';
import { CONTROL_HEADER, CONTROL_KEY, ControlTokens, type TokenStorage, controlHeaders, isValidToken, parseHeld } from './controlToken';

function memStorage(init: Record<string, string> = {}): TokenStorage & { data: Record<string, string> } {
  const data: Record<string, string> = { ...init };
  return {
    data,
    getItem: (k) => data[k] ?? null,
    setItem: (k, v) => void (data[k] = v),
    removeItem: (k) => void delete data[k],
  };
}

const T1 = 'Q2hvb3NlIGEgdG9rZW4_-x';
const T2 = 'another-token_2';

describe('isValidToken', () => {
  it('takes what the server issues and its header accepts', () => {
    expect(isValidToken(T1)).toBe(true);
    expect(isValidToken('a'.repeat(64))).toBe(true);
    expect(isValidToken('a'.repeat(65))).toBe(false);
    expect(isValidToken('')).toBe(false);
    expect(isValidToken('has space')).toBe(false);
    expect(isValidToken('ümlaut')).toBe(false);
    expect(isValidToken(null)).toBe(false);
  });
});

describe('parseHeld', () => {
  it('reads what the store wrote and rejects anything else', () => {
    expect(parseHeld(JSON.stringify({ token: T1, sessions: ['a', 'b', 'a'] }))).toEqual({ token: T1, sessions: ['a', 'b'] });
    expect(parseHeld(null)).toBeNull();
    expect(parseHeld('not json')).toBeNull();
    expect(parseHeld(JSON.stringify({ token: 'bad token', sessions: ['a'] }))).toBeNull();
    // A token that holds nothing is no token.
    expect(parseHeld(JSON.stringify({ token: T1, sessions: [] }))).toBeNull();
    expect(parseHeld(JSON.stringify({ token: T1, sessions: [1, ''] }))).toBeNull();
  });
});

describe('ControlTokens', () => {
  it('has no token until control is taken, and then sends it', () => {
    const tokens = new ControlTokens(memStorage());
    expect(tokens.token()).toBeNull();
    expect(controlHeaders(tokens)).toEqual({});
    tokens.took('drive-1', T1);
    expect(tokens.token()).toBe(T1);
    expect(tokens.holds('drive-1')).toBe(true);
    expect(controlHeaders(tokens)).toEqual({ [CONTROL_HEADER]: T1 });
  });

  it('serves every session with one token and clears it with the last release', () => {
    const s = memStorage();
    const tokens = new ControlTokens(s);
    tokens.took('drive-1', T1);
    tokens.took('drive-2', T1);
    tokens.took('drive-2', T1); // The holder taking again: the same token, listed once.
    expect(tokens.sessions()).toEqual(['drive-1', 'drive-2']);
    tokens.dropped('drive-1');
    expect(tokens.token()).toBe(T1);
    expect(tokens.holds('drive-1')).toBe(false);
    tokens.dropped('drive-1'); // Twice is harmless.
    tokens.dropped('drive-2');
    expect(tokens.token()).toBeNull();
    expect(s.data[CONTROL_KEY]).toBeUndefined();
  });

  it('keeps the token over a reload (the same tab storage), not in another tab', () => {
    const s = memStorage();
    new ControlTokens(s).took('drive-1', T1);
    const reloaded = new ControlTokens(s);
    expect(reloaded.token()).toBe(T1);
    expect(reloaded.holds('drive-1')).toBe(true);
    expect(new ControlTokens(memStorage()).token()).toBeNull();
  });

  it('starts afresh when the server answers another token (the old one lapsed)', () => {
    const tokens = new ControlTokens(memStorage());
    tokens.took('drive-1', T1);
    tokens.took('drive-2', T2);
    expect(tokens.token()).toBe(T2);
    expect(tokens.sessions()).toEqual(['drive-2']);
  });

  it('ignores a stored value it cannot use and an invalid token', () => {
    const tokens = new ControlTokens(memStorage({ [CONTROL_KEY]: '{"token":"x y","sessions":["a"]}' }));
    expect(tokens.token()).toBeNull();
    tokens.took('drive-1', 'not a token');
    expect(tokens.token()).toBeNull();
  });

  it('tells its listeners about every change', () => {
    const tokens = new ControlTokens(memStorage());
    let n = 0;
    const off = tokens.subscribe(() => n++);
    tokens.took('drive-1', T1);
    tokens.dropped('drive-1');
    tokens.dropped('drive-1'); // Nothing held: no change.
    off();
    tokens.took('drive-1', T1);
    expect(n).toBe(2);
  });

  it('works without storage (privacy mode): the token lives in memory', () => {
    const tokens = new ControlTokens(null);
    tokens.took('drive-1', T1);
    expect(tokens.token()).toBe(T1);
  });
});
