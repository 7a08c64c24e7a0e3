import { afterEach, describe, expect, it } from 'vitest';
import { holderText } from '../lib/control';
import { hasRight, me, rightBlocked } from './auth';

afterEach(() => me.set(undefined));

describe('rights from /auth/me', () => {
  it('says which right the role lacks, and allows what it has', () => {
    me.set({ user: 'otto', role: 'operator', rights: ['read', 'take_control', 'acknowledge_alarms'], mode: 'login', session: 's', idle_timeout_s: 900 });
    expect(hasRight('acknowledge_alarms')).toBe(true);
    expect(rightBlocked('acknowledge_alarms')).toBeNull();
    expect(rightBlocked('jog_home')).toBe('your role (operator) lacks the right "jog_home"; ask an administrator');
  });

  it('blocks nothing before the login is known (the server still checks)', () => {
    expect(rightBlocked('manage_users')).toBeNull();
  });
});

describe('the holder of control', () => {
  it('is named by user, with the client, once users exist', () => {
    expect(holderText('ui-1', 'eve')).toBe('user eve (client ui-1)');
    expect(holderText('ui-1', 'local')).toBe('client ui-1');
    expect(holderText('ui-1')).toBe('client ui-1');
  });
});
