import { describe, expect, it, vi } from 'vitest';
import { type ReportDeps, type ReportInfo, openReport } from './report';

const INFO: ReportInfo = {
  id: 'report-20261207t142600z-a1b2c3',
  drive_key: '5344534B-00000402-1',
  plant_tag: 'L2.Press.X',
  session: 'cia402-generic-1',
  time: '2026-12-07T14:26:00.000Z',
  by: 'engineer',
  sha256: 'ab'.repeat(32),
  html_sha256: 'cd'.repeat(32),
  pdf_sha256: null,
  url: '/api/v1/reports/report-20261207t142600z-a1b2c3.html',
  pdf_url: '/api/v1/reports/report-20261207t142600z-a1b2c3.pdf',
};

function fakeTab() {
  return { location: { href: '' }, close: vi.fn() };
}

describe('openReport', () => {
  it('opens the tab at once, then shows the report made in it', async () => {
    const tab = fakeTab();
    const order: string[] = [];
    const deps: ReportDeps = {
      openTab: () => (order.push('tab'), tab as unknown as Window),
      create: (sid) => (order.push(`create ${sid}`), Promise.resolve(INFO)),
      html: (rid) => (order.push(`html ${rid}`), Promise.resolve({ blob: new Blob(['<html>']) })),
      objectUrl: () => 'blob:report',
    };
    await expect(openReport('cia402-generic-1', deps)).resolves.toEqual(INFO);
    expect(order).toEqual(['tab', 'create cia402-generic-1', `html ${INFO.id}`]);
    expect(tab.location.href).toBe('blob:report');
    expect(tab.close).not.toHaveBeenCalled();
  });

  it('closes the tab again when the report cannot be made', async () => {
    const tab = fakeTab();
    const refused = new Error('lacks the right read_audit');
    const deps: ReportDeps = {
      openTab: () => tab as unknown as Window,
      create: () => Promise.reject(refused),
      html: () => Promise.reject(new Error('not reached')),
      objectUrl: () => 'blob:x',
    };
    await expect(openReport('s', deps)).rejects.toBe(refused);
    expect(tab.close).toHaveBeenCalledOnce();
  });
});
