/**
 * Where the viser 3D viewer is (GET /api/v1/viewer gives {enabled, url, port}): the URL the
 * iframe loads, or why there is none. A relative or host-less answer is resolved against the
 * page's own host, so the viewer works when the UI is opened from another machine.
 */
import type { ViewerInfo } from '../api/types';

export type ViewerTarget = { ok: true; src: string } | { ok: false; reason: string };

export function viewerTarget(info: ViewerInfo | null, page: { protocol: string; hostname: string; host: string }): ViewerTarget {
  if (!info) return { ok: false, reason: 'the server did not say where the 3D viewer is' };
  if (!info.enabled) {
    return { ok: false, reason: info.error ?? info.message ?? info.reason ?? 'the 3D viewer is switched off on this server' };
  }
  if (info.running === false) {
    return { ok: false, reason: info.error ? `the 3D viewer did not start: ${info.error}` : 'the 3D viewer is enabled but not running' };
  }
  const url = info.url?.trim();
  if (url) {
    if (/^https?:\/\//i.test(url)) {
      // A server bound to 0.0.0.0 / localhost names itself so; from another machine the page's
      // host is the one that reaches it.
      try {
        const u = new URL(url);
        if (['0.0.0.0', '127.0.0.1', 'localhost', '::', '[::]'].includes(u.hostname) && !isLoopback(page.hostname)) {
          u.hostname = page.hostname;
        }
        return { ok: true, src: u.toString() };
      } catch {
        return { ok: false, reason: `the viewer URL "${url}" is not valid` };
      }
    }
    if (url.startsWith('/')) return { ok: true, src: `${page.protocol}//${page.host}${url}` };
  }
  if (info.port) return { ok: true, src: `${page.protocol}//${page.hostname}:${info.port}/` };
  return { ok: false, reason: 'the viewer is enabled but the server gave neither its URL nor its port' };
}

function isLoopback(host: string): boolean {
  return host === 'localhost' || host === '127.0.0.1' || host === '::1' || host === '[::1]';
}
