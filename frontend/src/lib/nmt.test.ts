import { describe, expect, it } from 'vitest';
import { hasNmt, networkState, nmtTitle } from './nmt';

describe('nmtTitle', () => {
  it('says why the state is unknown', () => {
    expect(nmtTitle('unknown')).toContain('1017h');
    expect(nmtTitle(null)).toContain('no heartbeat');
  });
  it('says where a known state comes from', () => {
    expect(nmtTitle('preop')).toMatch(/^NMT state preop: from the drive's last heartbeat/);
  });
  it("says a CC-Link IE TSN station's state is its manager's", () => {
    expect(nmtTitle('unknown', 'cclink-ie-tsn')).toContain('manager');
    expect(nmtTitle('unknown', 'canopen')).toContain('1017h');
  });
  it('says PROFINET has no NMT and whose the state is', () => {
    expect(nmtTitle('unknown', 'profinet')).toMatch(/^No NMT on PROFINET/);
    expect(nmtTitle('unknown', 'profinet')).toContain('IO controller');
  });
});

describe('hasNmt', () => {
  it('is false where the link has no NMT to show', () => {
    expect(hasNmt('canopen')).toBe(true);
    expect(hasNmt('ethercat')).toBe(true);
    expect(hasNmt('profinet')).toBe(false);
    expect(hasNmt('cclink-ie-tsn')).toBe(false);
  });
});

describe('networkState', () => {
  it('says what each fieldbus has instead of a bare "unknown"', () => {
    expect(networkState({ link: 'canopen', nmt_state: 'preop' })).toMatchObject({ label: 'NMT', value: 'preop' });
    expect(networkState({ link: 'canopen', nmt_state: 'unknown' }).value).toBe('not reported (no heartbeat)');
    expect(networkState({ link: 'ethercat', nmt_state: 'safeop' })).toMatchObject({ label: 'AL state', value: 'safeop' });
    expect(networkState({ link: 'profinet', nmt_state: 'unknown', connected: true })).toMatchObject({ label: 'AR', value: "up (servodesk's supervisor AR)" });
    expect(networkState({ link: 'profinet', nmt_state: 'operational', connected: true }).value).toBe(
      "up (servodesk's supervisor AR and its IO AR: cyclic data)",
    );
    expect(networkState({ link: 'profinet', nmt_state: 'unknown', connected: false }).value).toMatch(/down/);
    expect(networkState({ link: 'cclink-ie-tsn', nmt_state: 'unknown', connected: true })).toMatchObject({ label: 'SLMP link', value: 'answering' });
  });
});
