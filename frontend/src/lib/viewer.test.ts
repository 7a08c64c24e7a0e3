import { describe, expect, it } from 'vitest';
import { viewerTarget } from './viewer';

const LOCAL = { protocol: 'http:', hostname: '127.0.0.1', host: '127.0.0.1:8000' };
const REMOTE = { protocol: 'http:', hostname: 'bench-pc', host: 'bench-pc:8000' };

describe('viewerTarget', () => {
  it('says why when the viewer is off', () => {
    expect(viewerTarget({ enabled: false, url: null, port: null }, LOCAL)).toEqual({
      ok: false,
      reason: 'the 3D viewer is switched off on this server',
    });
    expect(viewerTarget({ enabled: false, url: null, port: null, message: 'viser is not installed' }, LOCAL)).toEqual({
      ok: false,
      reason: 'viser is not installed',
    });
    expect(viewerTarget(null, LOCAL).ok).toBe(false);
    expect(viewerTarget({ enabled: true, running: false, url: 'http://127.0.0.1:8080/', port: 8080, error: 'port 8080 in use' }, LOCAL)).toEqual({
      ok: false,
      reason: 'the 3D viewer did not start: port 8080 in use',
    });
  });

  it('uses the absolute URL the server gives', () => {
    expect(viewerTarget({ enabled: true, url: 'http://127.0.0.1:8080', port: 8080 }, LOCAL)).toEqual({ ok: true, src: 'http://127.0.0.1:8080/' });
  });

  it('replaces a loopback or wildcard host by the page host when opened from another machine', () => {
    expect(viewerTarget({ enabled: true, url: 'http://0.0.0.0:8080/', port: 8080 }, REMOTE)).toEqual({ ok: true, src: 'http://bench-pc:8080/' });
  });

  it('resolves a path on the UI host and a bare port on the page host', () => {
    expect(viewerTarget({ enabled: true, url: '/viewer/', port: null }, LOCAL)).toEqual({ ok: true, src: 'http://127.0.0.1:8000/viewer/' });
    expect(viewerTarget({ enabled: true, url: null, port: 8081 }, REMOTE)).toEqual({ ok: true, src: 'http://bench-pc:8081/' });
    expect(viewerTarget({ enabled: true, url: null, port: null }, LOCAL).ok).toBe(false);
  });
});
