/**
 * Commissioning reports (docs/report.md, docs/api.md "Commissioning reports"): make one of a
 * connected drive, fetch its HTML or PDF. Endpoint functions on the one fetch wrapper
 * (`./http`), typed from the schema.
 */
import { apiDownload, apiRequest } from './http';
import type { components } from './schema';

export type ReportInfo = components['schemas']['ReportInfo'];

export const reportApi = {
  create: (sid: string) => apiRequest(`Make the report of ${sid}`, 'POST', '/sessions/{sid}/report', { params: { sid } }),
  html: (rid: string) => apiDownload(`Open report ${rid}`, '/reports/{rid}.html', { params: { rid } }),
  pdf: (rid: string) => apiDownload(`Print report ${rid}`, '/reports/{rid}.pdf', { params: { rid } }),
};

/** What opening a report needs from the browser and the API (replaced in the tests). */
export interface ReportDeps {
  create: (sid: string) => Promise<ReportInfo>;
  html: (rid: string) => Promise<{ blob: Blob }>;
  /** A new tab, opened before the first await: a browser lets a click open one, not a promise. */
  openTab: () => Window | null;
  objectUrl: (blob: Blob) => string;
}

const browserDeps: ReportDeps = {
  create: reportApi.create,
  html: reportApi.html,
  openTab: () => window.open('', '_blank'),
  objectUrl: (blob) => URL.createObjectURL(blob),
};

/**
 * Make the drive's report and show it in a new tab. The HTML is fetched with the tab's
 * credentials (a bearer token a plain link would not carry) and shown from a blob URL; the tab
 * is opened first and closed again when making the report fails. The report's metadata.
 */
export async function openReport(sid: string, deps: ReportDeps = browserDeps): Promise<ReportInfo> {
  const tab = deps.openTab();
  try {
    const info = await deps.create(sid);
    const file = await deps.html(info.id);
    const url = deps.objectUrl(new Blob([file.blob], { type: 'text/html' }));
    if (tab) tab.location.href = url;
    return info;
  } catch (e) {
    tab?.close();
    throw e;
  }
}
