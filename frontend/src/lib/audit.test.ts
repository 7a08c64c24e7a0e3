import { describe, expect, it } from 'vitest';
import { detailsText, localTime, localToIso } from './audit';

describe('audit page helpers', () => {
  it('sends a local datetime-local value as UTC ISO 8601, nothing for empty or invalid', () => {
    const local = '2026-12-07T09:30:05';
    expect(localToIso(local)).toBe(new Date(local).toISOString());
    expect(localToIso('')).toBeNull();
    expect(localToIso('not a time')).toBeNull();
  });

  it('shows a UTC record time in local time to the second, and bad text as it is', () => {
    const iso = '2026-12-07T08:30:00.123456Z';
    const d = new Date(iso);
    expect(localTime(iso)).toBe(
      `${d.getFullYear()}-12-${String(d.getDate()).padStart(2, '0')} ${String(d.getHours()).padStart(2, '0')}:${String(d.getMinutes()).padStart(2, '0')}:00`,
    );
    expect(localTime('garbage')).toBe('garbage');
  });

  it('writes details as key=value, objects as JSON, empty ones left out', () => {
    expect(detailsText({ status: 409, path: '/api/v1/x', none: null, empty: '', counts: { ok: 2 } })).toBe(
      'status=409 path=/api/v1/x counts={"ok":2}',
    );
  });
});
