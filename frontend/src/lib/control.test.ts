import { describe, expect, it } from 'vitest';
import { type ControlView, deadmanText, emptyView, energiseBlocked, holdsControl, writeBlocked } from './control';
import type { BindStatus } from '../ws/socket';

const BOUND: BindStatus = { state: 'bound', message: null, hint: null };
const UNBOUND: BindStatus = { state: 'unbound', message: null, hint: null };

function view(over: Partial<ControlView>): ControlView {
  return { ...emptyView('drive-1', UNBOUND), known: true, ...over };
}

describe('holdsControl', () => {
  it('needs the token and the server naming this tab', () => {
    expect(holdsControl(true, 'ui-1', 'ui-1', true)).toBe(true);
    // The label alone is no authority (a second tab or a script may use it).
    expect(holdsControl(true, 'ui-1', 'ui-1', false)).toBe(false);
    // A token the server no longer names: someone else holds it now.
    expect(holdsControl(true, 'ui-2', 'ui-1', true)).toBe(false);
    expect(holdsControl(true, null, 'ui-1', true)).toBe(false);
    expect(holdsControl(false, 'ui-1', 'ui-1', true)).toBe(false);
  });
});

describe('writeBlocked', () => {
  it('allows the holder', () => {
    expect(writeBlocked(view({ you: true, owner: 'ui-1' }))).toBeNull();
  });
  it('says to take control when nobody holds it', () => {
    expect(writeBlocked(view({}))).toMatch(/^nobody holds control of drive-1: take control first/);
  });
  it('names the holder, and says when its tab closed', () => {
    expect(writeBlocked(view({ owner: 'ui-2' }))).toMatch(/^client ui-2 holds control of drive-1: only the holder/);
    expect(writeBlocked(view({ owner: 'ui-2', orphaned: true }))).toContain('control lapses within 5 s');
  });
  it('waits for the first read', () => {
    expect(writeBlocked({ ...view({}), known: false })).toContain('reading who holds control');
  });
});

describe('energiseBlocked', () => {
  it('needs control and the bound dead-man link', () => {
    expect(energiseBlocked(view({ owner: 'ui-2' }))).toContain('client ui-2 holds control');
    expect(energiseBlocked(view({ you: true, owner: 'ui-1', bind: BOUND }))).toBeNull();
    expect(energiseBlocked(view({ you: true, owner: 'ui-1', bind: { state: 'pending', message: null, hint: null } }))).toContain('binding');
    expect(energiseBlocked(view({ you: true, owner: 'ui-1', bind: { state: 'refused', message: 'nobody holds control of drive-1', hint: null } }))).toBe(
      "the server refused this tab's dead-man link: nobody holds control of drive-1",
    );
    expect(energiseBlocked(view({ you: true, owner: 'ui-1', bind: { state: 'unbound', message: 'the WebSocket is closed', hint: null } }))).toBe(
      "this tab's dead-man link is not bound: the WebSocket is closed",
    );
  });
});

describe('deadmanText', () => {
  it('is short for the header', () => {
    expect(deadmanText(view({ bind: BOUND }))).toBe('dead-man bound');
    expect(deadmanText(view({}))).toBe('dead-man NOT bound');
  });
});
