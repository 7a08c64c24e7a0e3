/**
 * REST client and shapes of the live scope (issue 7, docs/scope.md "REST", `/api/v1/scope...`),
 * and the address of its binary WebSocket.
 *
 * The scope belongs to the application, not to one session: its channels may come from
 * several drives. Requests carry the same headers as the shared client (token, the tab's
 * client id); files (exports) come back as bytes with the name the server gave them, and an
 * import sends the file's bytes as they are (CSV text or an MDF4 binary).
 */
import { getToken } from './auth';
import { API_BASE, ApiError, type DownloadedFile, fileForm, filenameFromDisposition, normaliseErrorBody } from './client';
import type { ApiErrorBody } from './types';
import { CLIENT_HEADER, tabClientId } from '../lib/backupClientId';
import { controlHeaders } from '../lib/controlToken';

/** Where a channel's samples come from; `auto` lets the server choose (docs/scope.md "Model"). */
export type ScopeSource = 'auto' | 'pdo' | 'sdo' | 'recorder';
/** A source the server achieved (never `auto`). */
export type AchievedSource = Exclude<ScopeSource, 'auto'>;

/** One channel as the page sends it (PUT /scope/channels). */
export interface ScopeChannelConfig {
  /** 0..7. */
  id: number;
  session: string;
  /** "0x6064:00". */
  address: string;
  source: ScopeSource;
  /** Per-channel display scale and offset: shown = engineering x scale + offset. */
  scale: number;
  offset: number;
  visible: boolean;
  label: string | null;
  /** Requested rate (SDO poll, recorder sample rate); 0: as fast as it goes. */
  rate_hz?: number;
}

/** One channel as the server reports it (ScopeStatus.channels). */
export interface ScopeChannelStatus {
  id: number;
  session: string;
  address: string;
  name: string | null;
  /** Engineering unit (profile). */
  unit: string | null;
  /** Unit of the raw value as the drive holds it (profile). */
  raw_unit: string | null;
  scale: number;
  offset: number;
  visible: boolean;
  label: string | null;
  /** The source the channel got; null while the scope has not started it. */
  source: AchievedSource | null;
  requested_source: ScopeSource;
  /** Achieved sample rate (measured, the spacing of the samples), null before there is one. */
  rate_hz: number | null;
  /** Samples per second that arrived over the last seconds (a recorder's uploads leave gaps). */
  throughput_hz?: number | null;
  samples: number;
  error: string | null;
  /** Raw to engineering factor of the profile (engineering = raw x eng_scale). */
  eng_scale: number | null;
  requested_rate_hz?: number | null;
}

export type TriggerMode = 'roll' | 'single' | 'normal';
export type TriggerKind = 'level' | 'edge' | 'state' | 'fault';
export type TriggerSlope = 'rising' | 'falling' | 'either';

export interface ScopeTrigger {
  mode: TriggerMode;
  kind: TriggerKind;
  channel: number;
  level: number;
  slope: TriggerSlope;
  /** Fraction of the window before the trigger, 0..1. */
  pre: number;
  window_s: number;
  holdoff_s: number;
}

export type ScopeState = 'idle' | 'rolling' | 'armed' | 'triggered' | 'done';

export interface ScopeStatus {
  running: boolean;
  state: ScopeState;
  trigger: ScopeTrigger;
  channels: ScopeChannelStatus[];
  clients: number;
  buffer_s: number;
}

/** One channel of a recording (a capture, or an imported file). */
export interface RecordingChannel {
  id: number;
  /** Backend times (a capture) or seconds from t_ref (an imported file). */
  t: (number | null)[];
  /** Raw values; null where a file has no sample. */
  v: (number | null)[];
  label?: string | null;
  name?: string | null;
  unit?: string | null;
  raw_unit?: string | null;
  address?: string | null;
  session?: string | null;
  source?: string | null;
  /** The profile's raw to engineering factor (engineering = raw x scale). */
  scale?: number | null;
  eng_scale?: number | null;
  /** A capture: the channel's display scale and offset (shown = engineering x it + offset). */
  display_scale?: number | null;
  offset?: number | null;
}

/** GET /scope/capture and POST /scope/import. */
export interface ScopeRecording {
  t_ref: number;
  trigger_time: number | null;
  channels: RecordingChannel[];
}

/** GET /sessions/{sid}/recorder: the drive-side recorder. */
export interface RecorderInfo {
  present: boolean;
  max_channels: number;
  rate_hz: number;
  depth: number;
  objects: string[];
}

export type ScopeExportFormat = 'csv' | 'mdf4';
export type ScopeExportWindow = 'capture' | 'buffer';

/** The scope stream's URL, with the token when there is one. */
export function scopeSocketUrl(): string {
  const proto = window.location.protocol === 'https:' ? 'wss:' : 'ws:';
  const url = new URL(`${proto}//${window.location.host}${API_BASE}/scope/ws`);
  const token = getToken();
  if (token) url.searchParams.set('token', token);
  return url.toString();
}

const NETWORK_ERROR: ApiErrorBody = {
  error: 'NetworkError',
  message: 'the servodesk server did not answer',
  hint: 'check that "servodesk serve" is still running and reachable from this browser',
};

function headers(contentType: string | null): Record<string, string> {
  const h: Record<string, string> = { Accept: 'application/json', [CLIENT_HEADER]: tabClientId(), ...controlHeaders() };
  const token = getToken();
  if (token) h.Authorization = `Bearer ${token}`;
  if (contentType) h['Content-Type'] = contentType;
  return h;
}

async function send(action: string, method: string, path: string, body: BodyInit | null, contentType: string | null): Promise<Response> {
  try {
    return await fetch(API_BASE + path, { method, headers: headers(body === null ? null : contentType), body });
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
  throw new ApiError(action, res.status, normaliseErrorBody(res.status, res.statusText, payload));
}

async function request<T>(action: string, method: string, path: string, body?: unknown): Promise<T> {
  const res = await send(action, method, path, body === undefined ? null : JSON.stringify(body), 'application/json');
  if (!res.ok) return fail(action, res);
  const text = await res.text();
  return (text ? JSON.parse(text) : null) as T;
}

async function fetchFile(action: string, path: string): Promise<DownloadedFile> {
  const res = await send(action, 'GET', path, null, null);
  if (!res.ok) return fail(action, res);
  return { blob: await res.blob(), filename: filenameFromDisposition(res.headers.get('Content-Disposition')) };
}

export const scopeApi = {
  status: () => request<ScopeStatus>('Read the scope', 'GET', '/scope'),
  setChannels: (channels: ScopeChannelConfig[]) =>
    request<ScopeStatus>('Set the scope channels', 'PUT', '/scope/channels', { channels }),
  setTrigger: (trigger: ScopeTrigger) => request<ScopeStatus>('Set the trigger', 'PUT', '/scope/trigger', trigger),
  run: (action: 'start' | 'stop' | 'arm') =>
    request<ScopeStatus>({ start: 'Start the scope', stop: 'Stop the scope', arm: 'Arm the trigger' }[action], 'POST', '/scope/run', { action }),
  capture: () => request<ScopeRecording>('Load the captured window', 'GET', '/scope/capture'),
  export: (format: ScopeExportFormat, window: ScopeExportWindow) =>
    fetchFile(`Export the recording as ${format === 'csv' ? 'CSV' : 'MDF4'}`, `/scope/export?format=${format}&window=${window}`),
  /** Send a recording file (CSV or MDF4) as it is; the answer is the recording to open. */
  import: async (filename: string, bytes: ArrayBuffer): Promise<ScopeRecording> => {
    const action = `Import ${filename}`;
    // multipart/form-data (field `file`, docs/security.md); the browser sets the type.
    const res = await send(action, 'POST', `/scope/import?filename=${encodeURIComponent(filename)}`, fileForm(filename, bytes), null);
    if (!res.ok) return fail(action, res);
    return (await res.json()) as ScopeRecording;
  },
  recorder: (sid: string) =>
    request<RecorderInfo>('Read the drive-side recorder', 'GET', `/sessions/${encodeURIComponent(sid)}/recorder`),
};
