/**
 * REST client and shapes of the live scope (issue 7, docs/scope.md "REST", `/api/v1/scope...`),
 * and the address of its binary WebSocket.
 *
 * The scope belongs to the application, not to one session: its channels may come from
 * several drives. Requests go through the one fetch wrapper (`./http`); files (exports) come
 * back as bytes with the name the server gave them, and an import sends the file's bytes as
 * they are (CSV text or an MDF4 binary). The answers are the schema's types
 * (api/schemas_scope.py); the channel configuration is the UI's body (checked against it).
 */
import { getToken } from './auth';
import { API_BASE, apiDownload, apiRequest, fileForm } from './http';
import type { components } from './schema';

type S = components['schemas'];

/** Where a channel's samples come from; `auto` lets the server choose (docs/scope.md "Model"). */
export type ScopeSource = 'auto' | 'pdo' | 'sdo' | 'recorder';
/** A source the server achieved (never `auto`). */
export type AchievedSource = S['ScopeChannelStatus']['source'];

/** One channel as the page sends it (PUT /scope/channels). */
export interface ScopeChannelConfig {
  /** 0..31 (MAX_CHANNELS in components/scope/ChannelTable.tsx). */
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
export type ScopeChannelStatus = S['ScopeChannelStatus'];

export type ScopeTrigger = S['ScopeTrigger'];
export type TriggerMode = ScopeTrigger['mode'];
export type TriggerKind = ScopeTrigger['kind'];
export type TriggerSlope = ScopeTrigger['slope'];

export type ScopeState = S['ScopeStatus']['state'];

export type ScopeStatus = S['ScopeStatus'];

/** The JSON body of the stream's status frame (kind 3): ScopeStatus, tagged. */
export type ScopeStatusFrame = S['ScopeStatusFrame'];

/** One channel of a recording (a capture, or an imported file). */
export type RecordingChannel = S['RecordingChannel'];

/** GET /scope/capture and POST /scope/import. */
export type ScopeRecording = S['ScopeRecording'];

/** GET /sessions/{sid}/recorder: the drive-side recorder. */
export type RecorderInfo = S['RecorderInfo'];

/** A scope capture kept in the store (issue 49, docs/scope.md "Kept captures"): metadata. */
export type CaptureInfo = S['CaptureInfo'];
export type CaptureChannelInfo = S['CaptureChannelInfo'];
/** GET /scope/captures/{id}: with every sample and the trigger. */
export type StoredCapture = S['StoredCapture'];
export type CaptureKeep = S['CaptureKeep'];

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

export const scopeApi = {
  status: () => apiRequest('Read the scope', 'GET', '/scope'),
  setChannels: (channels: ScopeChannelConfig[]) =>
    // A channel may leave out rate_hz (the server's default): ServerDefaults one level down.
    apiRequest('Set the scope channels', 'PUT', '/scope/channels', { body: { channels } as S['ChannelsIn'] }),
  setTrigger: (trigger: ScopeTrigger) => apiRequest('Set the trigger', 'PUT', '/scope/trigger', { body: trigger }),
  run: (action: 'start' | 'stop' | 'arm') =>
    apiRequest({ start: 'Start the scope', stop: 'Stop the scope', arm: 'Arm the trigger' }[action], 'POST', '/scope/run', {
      body: { action },
    }),
  capture: () => apiRequest('Load the captured window', 'GET', '/scope/capture'),
  export: (format: ScopeExportFormat, window: ScopeExportWindow) =>
    apiDownload(`Export the recording as ${format === 'csv' ? 'CSV' : 'MDF4'}`, '/scope/export', { query: { format, window } }),
  /** Send a recording file (CSV or MDF4) as it is; the answer is the recording to open. */
  import: (filename: string, bytes: ArrayBuffer) =>
    // multipart/form-data (field `file`, docs/security.md); the browser sets the type.
    apiRequest(`Import ${filename}`, 'POST', '/scope/import', { query: { filename }, body: fileForm(filename, bytes) }),
  recorder: (sid: string) => apiRequest('Read the drive-side recorder', 'GET', '/sessions/{sid}/recorder', { params: { sid } }),
  // Kept captures: the store's, per drive (from every session and gateway).
  keep: (sid: string, body: CaptureKeep) => apiRequest('Keep the capture', 'POST', '/sessions/{sid}/scope/captures', { params: { sid }, body }),
  kept: (sid: string) => apiRequest('List the kept captures', 'GET', '/sessions/{sid}/scope/captures', { params: { sid } }),
  keptOne: (cid: string) => apiRequest('Open the kept capture', 'GET', '/scope/captures/{cid}', { params: { cid } }),
  keptCsv: (cid: string) => apiDownload('Export the kept capture as CSV', '/scope/captures/{cid}.csv', { params: { cid } }),
  attach: (cid: string, attached: boolean) =>
    apiRequest(attached ? 'Attach the capture to the report' : 'Detach the capture from the report', 'PATCH', '/scope/captures/{cid}', {
      params: { cid },
      body: { attached },
    }),
  forget: (cid: string, reason: string) =>
    apiRequest('Delete the kept capture', 'DELETE', '/scope/captures/{cid}', { params: { cid }, body: { reason } }),
};
