/**
 * REST client of the PDO mapping and cyclic data routes (docs/pdo.md "REST",
 * `/api/v1/sessions/{sid}/pdo...`).
 *
 * It sends the same headers as the shared client (token, the tab's client id, which the
 * server needs for control ownership and records in the audit log), and keeps what the shared
 * client drops: a refused mapping answers 422 with the `problems` that name the PDO, entry
 * and field, which the page shows in place, so they travel in {@link PdoRefusedError}.
 */
import { getToken } from './auth';
import { API_BASE, ApiError, type DownloadedFile, filenameFromDisposition, normaliseErrorBody } from './client';
import type {
  ApiErrorBody,
  PdoApplyReport,
  PdoApplyRequest,
  PdoCyclicRequest,
  PdoCyclicStatus,
  PdoExportFormat,
  PdoLayout,
  PdoMappable,
  PdoPlan,
  PdoProblem,
  PdoTemplate,
  PdoValidation,
  PdoView,
} from './types';
import { CLIENT_HEADER, tabClientId } from '../lib/backupClientId';
import { controlHeaders } from '../lib/controlToken';

/** A mapping the server refused before writing anything, with the problems it named. */
export class PdoRefusedError extends ApiError {
  readonly problems: PdoProblem[];

  constructor(action: string, status: number, body: ApiErrorBody, problems: PdoProblem[]) {
    super(action, status, body);
    this.name = 'PdoRefusedError';
    this.problems = problems;
  }
}

function str(v: unknown): string | null {
  return typeof v === 'string' ? v : null;
}

function int(v: unknown): number | null {
  return typeof v === 'number' && Number.isInteger(v) ? v : null;
}

/** The `problems` of an error answer, in the contract's shape; [] when there are none. */
export function problemsOf(payload: unknown): PdoProblem[] {
  if (!payload || typeof payload !== 'object') return [];
  const raw = (payload as { problems?: unknown }).problems;
  if (!Array.isArray(raw)) return [];
  const out: PdoProblem[] = [];
  for (const p of raw) {
    if (!p || typeof p !== 'object') continue;
    const o = p as Record<string, unknown>;
    const message = str(o.message);
    if (!message) continue;
    out.push({ message, pdo: str(o.pdo), entry: int(o.entry), field: str(o.field), section: str(o.section) });
  }
  return out;
}

function headers(json: boolean): Record<string, string> {
  const h: Record<string, string> = { Accept: 'application/json', [CLIENT_HEADER]: tabClientId(), ...controlHeaders() };
  const token = getToken();
  if (token) h.Authorization = `Bearer ${token}`;
  if (json) h['Content-Type'] = 'application/json';
  return h;
}

const NETWORK_ERROR: ApiErrorBody = {
  error: 'NetworkError',
  message: 'the servodesk server did not answer',
  hint: 'check that "servodesk serve" is still running and reachable from this browser',
};

async function send(action: string, method: string, path: string, body?: unknown): Promise<Response> {
  try {
    return await fetch(API_BASE + path, {
      method,
      headers: headers(body !== undefined),
      body: body === undefined ? null : JSON.stringify(body),
    });
  } catch {
    throw new ApiError(action, 0, NETWORK_ERROR);
  }
}

async function fail(action: string, res: Response): Promise<never> {
  const text = await res.text();
  let payload: unknown = text;
  try {
    payload = text ? JSON.parse(text) : null;
  } catch {
    // Keep the text: normaliseErrorBody shows it when it is short.
  }
  const body = normaliseErrorBody(res.status, res.statusText, payload);
  const problems = problemsOf(payload);
  if (problems.length) {
    // The contract's 422 is {"detail", "problems"}: a sentence for the box above the tables.
    if (body.message.startsWith('the server answered')) body.message = problems.map((p) => p.message).join('; ');
    throw new PdoRefusedError(action, res.status, body, problems);
  }
  throw new ApiError(action, res.status, body);
}

async function request<T>(action: string, method: string, path: string, body?: unknown): Promise<T> {
  const res = await send(action, method, path, body);
  if (!res.ok) return fail(action, res);
  if (res.status === 204) return undefined as T;
  const text = await res.text();
  return (text ? JSON.parse(text) : null) as T;
}

async function fetchFile(action: string, path: string): Promise<DownloadedFile> {
  const res = await send(action, 'GET', path);
  if (!res.ok) return fail(action, res);
  return { blob: await res.blob(), filename: filenameFromDisposition(res.headers.get('Content-Disposition')) };
}

const base = (sid: string) => `/sessions/${encodeURIComponent(sid)}/pdo`;

export const pdoApi = {
  /** The drive's PDO configuration, read now. */
  view: (sid: string) => request<PdoView>('Read the PDO configuration', 'GET', base(sid)),
  mappable: (sid: string) => request<PdoMappable>('Load the mappable objects', 'GET', `${base(sid)}/mappable`),
  templates: (sid: string) => request<PdoTemplate[]>('Load the PDO templates', 'GET', `${base(sid)}/templates`),
  /** The template applied to the current configuration; nothing is written. */
  template: (sid: string, id: string, name: string) =>
    request<PdoView>(`Load template ${name}`, 'POST', `${base(sid)}/templates/${encodeURIComponent(id)}`, {}),
  validate: (sid: string, layout: PdoLayout) =>
    request<PdoValidation>('Check the mapping', 'POST', `${base(sid)}/validate`, layout),
  plan: (sid: string, layout: PdoLayout) => request<PdoPlan>('Plan the mapping', 'POST', `${base(sid)}/plan`, layout),
  apply: (sid: string, body: PdoApplyRequest) =>
    request<PdoApplyReport>(body.dry_run ? 'Dry-run the mapping' : 'Apply the mapping', 'POST', `${base(sid)}/apply`, body),
  export: (sid: string, format: PdoExportFormat) =>
    fetchFile(`Export the mapping as ${format.toUpperCase()}`, `${base(sid)}/export?format=${format}`),
  cyclic: (sid: string) => request<PdoCyclicStatus>('Read the cyclic data status', 'GET', `${base(sid)}/cyclic`),
  startCyclic: (sid: string, body: PdoCyclicRequest) =>
    request<PdoCyclicStatus>('Start cyclic data', 'POST', `${base(sid)}/cyclic`, body),
  stopCyclic: (sid: string) => request<PdoCyclicStatus>('Stop cyclic data', 'DELETE', `${base(sid)}/cyclic`),
  setOutputs: (sid: string, values: Record<string, number>) =>
    request<PdoCyclicStatus>('Set the cyclic outputs', 'PUT', `${base(sid)}/cyclic/outputs`, { values }),
};
