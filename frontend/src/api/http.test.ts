import { afterEach, describe, expect, it, vi } from 'vitest';
import { me } from './auth';
import {
  ApiError,
  PdoRefusedError,
  apiDownload,
  apiRequest,
  apiUrl,
  errorOf,
  fillPath,
  filenameFromDisposition,
  queryText,
} from './http';
import type { BackupFormat, DeviceDescriptionFormat, PdoExportFormat } from './types';

interface Sent {
  url: string;
  init: RequestInit;
}

/** Stand in for the network: record what the wrapper sends, answer `status` with `body`. */
function answer(status: number, body: unknown, headers: Record<string, string> = {}): Sent[] {
  const sent: Sent[] = [];
  vi.stubGlobal('fetch', (url: string, init: RequestInit) => {
    sent.push({ url, init });
    const text = body === undefined ? null : typeof body === 'string' ? body : JSON.stringify(body);
    return Promise.resolve(new Response(status === 204 ? null : text, { status, headers }));
  });
  return sent;
}

afterEach(() => {
  vi.unstubAllGlobals();
  me.set(undefined);
});

describe('paths and queries', () => {
  it('fills each {name} with its value encoded as one segment', () => {
    expect(fillPath('/sessions/{sid}/objects/{address}', { sid: 'a/b', address: '0x6041:00' })).toBe(
      '/sessions/a%2Fb/objects/0x6041%3A00',
    );
    expect(() => fillPath('/sessions/{sid}', {})).toThrow(/no value for \{sid\}/);
  });

  it('leaves unset query parameters out', () => {
    expect(queryText({ drive: null, profile: undefined, limit: 100, q: '', since: 'a b' })).toBe('?limit=100&since=a%20b');
    expect(queryText(undefined)).toBe('');
  });

  it('builds a plain link with the same rules', () => {
    expect(apiUrl('/profiles/{profile_id}/export', { params: { profile_id: 'x y' }, query: { format: 'eds' } })).toBe(
      '/api/v1/profiles/x%20y/export?format=eds',
    );
  });
});

describe('requests', () => {
  it('sends JSON with the client label and answers the parsed body', async () => {
    const sent = answer(200, { address: '0x6041:00', value: 7 });
    const out = await apiRequest('Write 0x6041:00', 'PUT', '/sessions/{sid}/objects/{address}', {
      params: { sid: 's1', address: '0x6041:00' },
      body: { value: 7 },
    });
    expect(out).toMatchObject({ value: 7 });
    expect(sent).toHaveLength(1);
    const { url, init } = sent[0]!;
    expect(url).toBe('/api/v1/sessions/s1/objects/0x6041%3A00');
    expect(init.method).toBe('PUT');
    expect(init.body).toBe('{"value":7}');
    const h = init.headers as Record<string, string>;
    expect(h['Content-Type']).toBe('application/json');
    expect(h['X-Servodesk-Client']).toMatch(/\S/);
  });

  it('sends no body and no JSON type where the route takes none; 204 answers undefined', async () => {
    const sent = answer(204, undefined);
    expect(await apiRequest('Close session s1', 'DELETE', '/sessions/{sid}', { params: { sid: 's1' } })).toBeUndefined();
    expect(sent[0]!.init.body).toBeNull();
    expect((sent[0]!.init.headers as Record<string, string>)['Content-Type']).toBeUndefined();
  });

  it('sends a file as multipart, leaving its type to the browser', async () => {
    const sent = answer(201, { id: 'p' });
    const form = new FormData();
    form.append('file', new Blob(['x']), 'a.eds');
    await apiRequest('Import a.eds', 'POST', '/profiles/import', { query: { filename: 'a.eds' }, body: form });
    expect(sent[0]!.url).toBe('/api/v1/profiles/import?filename=a.eds');
    expect(sent[0]!.init.body).toBe(form);
    expect((sent[0]!.init.headers as Record<string, string>)['Content-Type']).toBeUndefined();
  });

  it('keeps the stop going out when the tab closes', async () => {
    const sent = answer(200, { user: 'u', sessions: [], stopped: 0, failed: 0, pending: 0 });
    await apiRequest('Stop all', 'POST', '/motion/stop-all', { keepalive: true });
    expect(sent[0]!.init.keepalive).toBe(true);
  });
});

describe('errors', () => {
  it("carries the server's message, code and hint, and what the user was doing", async () => {
    answer(400, { error: 'ObjectAccessError', message: 'refused', code: 0x06010002, code_hex: '0x06010002', hint: 'read only' });
    const e = await apiRequest('Write 0x1000:00', 'PUT', '/sessions/{sid}/objects/{address}', {
      params: { sid: 's', address: '0x1000:00' },
      body: { value: 1 },
    }).catch((x: unknown) => x);
    expect(e).toBeInstanceOf(ApiError);
    const err = e as ApiError;
    expect([err.action, err.status, err.message, err.body.code_hex, err.body.hint]).toEqual([
      'Write 0x1000:00',
      400,
      'refused',
      '0x06010002',
      'read only',
    ]);
  });

  it('says the server did not answer, or what the caller says instead', async () => {
    vi.stubGlobal('fetch', () => Promise.reject(new TypeError('Failed to fetch')));
    const e = (await apiRequest('Check the server', 'GET', '/health').catch((x: unknown) => x)) as ApiError;
    expect([e.status, e.body.error, e.message]).toEqual([0, 'NetworkError', 'the servodesk server did not answer']);
    const stop = (await apiRequest('Stop all', 'POST', '/motion/stop-all', {
      networkError: { error: 'NetworkError', message: 'the stop may not have been sent' },
    }).catch((x: unknown) => x)) as ApiError;
    expect(stop.message).toBe('the stop may not have been sent');
  });

  it('raises a refused mapping with its problems', () => {
    const e = errorOf('Apply the mapping', 422, 'Unprocessable', {
      detail: 'refused',
      problems: [{ message: 'too long', pdo: 'RPDO1', entry: 2, field: 'bits' }, { pdo: 'no message' }],
    });
    expect(e).toBeInstanceOf(PdoRefusedError);
    expect((e as PdoRefusedError).problems).toEqual([{ message: 'too long', pdo: 'RPDO1', entry: 2, field: 'bits', section: null }]);
    expect(errorOf('Read', 502, 'Bad Gateway', 'upstream down')).not.toBeInstanceOf(PdoRefusedError);
    expect(errorOf('Read', 502, 'Bad Gateway', 'upstream down').message).toBe('upstream down');
  });

  it('keeps fields the error schema does not list (a lock-out says until when)', async () => {
    answer(429, { error: 'LockedOut', message: 'too many failed logins', until: 1234 });
    const e = (await apiRequest('Log in', 'POST', '/auth/login', {
      body: { user: 'a', password: 'b' },
      authLost: false,
    }).catch((x: unknown) => x)) as ApiError;
    expect(e.status).toBe(429);
    expect((e.payload as { until: number }).until).toBe(1234);
  });

  it('a 401 means the login is gone, except where the caller asks it', async () => {
    me.set({ user: 'eve', role: 'engineer', rights: [], mode: 'login', session: 's', idle_timeout_s: 900 });
    const sent = answer(401, { error: 'Unauthorized', message: 'log in' });
    await apiRequest('Log in', 'POST', '/auth/login', { body: { user: 'a', password: 'b' }, authLost: false }).catch(() => null);
    expect(sent).toHaveLength(1);
    await apiRequest('List the sessions', 'GET', '/sessions').catch(() => null);
    // authLost asks GET /auth/me who is logged in now.
    await vi.waitFor(() => expect(sent.map((s) => s.url)).toContain('/api/v1/auth/me'));
  });
});

describe('downloads', () => {
  it("returns the bytes and the server's file name", async () => {
    answer(200, 'a;b\n', { 'Content-Disposition': 'attachment; filename="x.csv"; filename*=UTF-8\'\'m%C3%BC.csv' });
    const f = await apiDownload('Export', '/audit/export', { query: { format: 'csv' } });
    expect(f.filename).toBe('mü.csv');
    expect(await f.blob.text()).toBe('a;b\n');
    expect(filenameFromDisposition('attachment; filename=plain.json')).toBe('plain.json');
    expect(filenameFromDisposition(null)).toBeNull();
  });
});

// Compile-time checks (tsc --noEmit runs over this file): the schema rejects what the server
// would not take. Each line must stay an error; the closure is never called.
export const typeChecks = () => [
  // @ts-expect-error a path the API does not serve
  apiRequest('x', 'GET', '/sessions/{sid}/nothing', { params: { sid: 's' } }),
  // @ts-expect-error a method the path does not answer
  apiRequest('x', 'DELETE', '/health'),
  // @ts-expect-error a path parameter missing
  apiRequest('x', 'GET', '/sessions/{sid}/state'),
  // @ts-expect-error a body of the wrong shape
  apiRequest('x', 'POST', '/sessions/{sid}/state', { params: { sid: 's' }, body: { command: 'jump' } }),
  // The download formats come from the routes' query parameters (never would refuse these).
  ['esi', 'csv', 'json'] satisfies [DeviceDescriptionFormat, BackupFormat, PdoExportFormat],
  // @ts-expect-error a format the backup download does not offer
  'esi' satisfies BackupFormat,
];
