/**
 * REST client and shapes of the live scope (issue 7, docs/scope.md "REST", `/api/v1/scope...`),
 * and the address of its binary WebSocket.
 *
 * The scope belongs to the application, not to one session: its channels may come from
 * several drives. Requests go through the one fetch wrapper (`./http`); files (exports) come
 * back as bytes with the name the server gave them, and an import sends the file's bytes as
 * they are (CSV text or an MDF4 binary). The routes still answer `dict[str, Any]` (issue 51
 * item 1): the shapes below are the UI's until the backend gives them response models.
 */
import { getToken } from './auth';
import { API_BASE, apiDownload, apiRequest, fileForm, untyped } from './http';
import type { components } from './schema';

type S = components['schemas'];

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

export const scopeApi = {
  status: () => untyped(apiRequest('Read the scope', 'GET', '/scope')) as Promise<ScopeStatus>,
  setChannels: (channels: ScopeChannelConfig[]) =>
    // A channel may leave out rate_hz (the server's default): ServerDefaults one level down.
    untyped(
      apiRequest('Set the scope channels', 'PUT', '/scope/channels', { body: { channels } as S['ChannelsIn'] }),
    ) as Promise<ScopeStatus>,
  setTrigger: (trigger: ScopeTrigger) =>
    untyped(apiRequest('Set the trigger', 'PUT', '/scope/trigger', { body: trigger })) as Promise<ScopeStatus>,
  run: (action: 'start' | 'stop' | 'arm') =>
    untyped(
      apiRequest({ start: 'Start the scope', stop: 'Stop the scope', arm: 'Arm the trigger' }[action], 'POST', '/scope/run', {
        body: { action },
      }),
    ) as Promise<ScopeStatus>,
  capture: () => untyped(apiRequest('Load the captured window', 'GET', '/scope/capture')) as Promise<ScopeRecording>,
  export: (format: ScopeExportFormat, window: ScopeExportWindow) =>
    apiDownload(`Export the recording as ${format === 'csv' ? 'CSV' : 'MDF4'}`, '/scope/export', { query: { format, window } }),
  /** Send a recording file (CSV or MDF4) as it is; the answer is the recording to open. */
  import: (filename: string, bytes: ArrayBuffer) =>
    // multipart/form-data (field `file`, docs/security.md); the browser sets the type.
    untyped(
      apiRequest(`Import ${filename}`, 'POST', '/scope/import', { query: { filename }, body: fileForm(filename, bytes) }),
    ) as Promise<ScopeRecording>,
  recorder: (sid: string) =>
    untyped(apiRequest('Read the drive-side recorder', 'GET', '/sessions/{sid}/recorder', { params: { sid } })) as Promise<RecorderInfo>,
};
