/**
 * Typed REST client for /api/v1 (docs/api.md).
 *
 * Every failure becomes an {@link ApiError} that carries the server's error body, so the UI
 * can say what failed, why (message, protocol code and its meaning) and what to do (hint)
 * instead of showing JSON.
 */
import { authLost, getToken } from './auth';
import { controlHeaders } from '../lib/controlToken';
import type {
  ApiErrorBody,
  DcpDone,
  DcpIdentifyRequest,
  DcpIdentifyResult,
  DcpSetRequest,
  DriveState,
  Health,
  ObjectValue,
  ObjectWrite,
  ProfileSummary,
  ScanRequest,
  ScanResult,
  SessionInfo,
  SessionRequest,
  StateCommand,
} from './index';
import type {
  DeviceDescriptionFormat,
  ProfileDetail,
  ReadResponse,
  RestoreDefaultsRequest,
  RestoreDefaultsResult,
  StoreResult,
} from './types';

export const API_BASE = '/api/v1';

export class ApiError extends Error {
  readonly status: number;
  readonly body: ApiErrorBody;
  /** What the user was doing, e.g. "Write 0x6041:00". */
  readonly action: string;

  constructor(action: string, status: number, body: ApiErrorBody) {
    super(body.message);
    this.name = 'ApiError';
    this.action = action;
    this.status = status;
    this.body = body;
  }
}

/** Turn any error body the server may send into the documented shape. */
export function normaliseErrorBody(status: number, statusText: string, payload: unknown): ApiErrorBody {
  if (payload !== null && typeof payload === 'object') {
    const p = payload as Record<string, unknown>;
    if (typeof p.message === 'string') {
      return {
        error: typeof p.error === 'string' ? p.error : `HTTP ${status}`,
        message: p.message,
        hint: typeof p.hint === 'string' ? p.hint : null,
        field: typeof p.field === 'string' ? p.field : null,
        code: typeof p.code === 'number' ? p.code : null,
        code_hex: typeof p.code_hex === 'string' ? p.code_hex : null,
        meaning: typeof p.meaning === 'string' ? p.meaning : null,
        protocol: typeof p.protocol === 'string' ? p.protocol : null,
        address: typeof p.address === 'string' ? p.address : null,
      };
    }
    // FastAPI's default shape ({"detail": ...}); the contract says the server maps it, but a
    // person should still read a sentence if it slips through.
    const detail = p.detail;
    if (typeof detail === 'string') return { error: `HTTP ${status}`, message: detail };
    if (Array.isArray(detail)) {
      const parts = detail.map((d: unknown) => {
        if (d && typeof d === 'object') {
          const e = d as { loc?: unknown; msg?: unknown };
          const loc = Array.isArray(e.loc) ? e.loc.filter((x) => x !== 'body').join('.') : '';
          const msg = typeof e.msg === 'string' ? e.msg : 'invalid';
          return loc ? `${loc}: ${msg}` : msg;
        }
        return String(d);
      });
      return { error: `HTTP ${status}`, message: parts.join('; ') };
    }
  }
  const text = typeof payload === 'string' && payload.trim() && payload.length < 300 ? payload.trim() : '';
  return {
    error: `HTTP ${status}`,
    message: text || `the server answered ${status} ${statusText}`.trim(),
    hint: status === 401 ? 'log in again (your session ended)' : null,
  };
}

async function request<T>(
  action: string,
  method: string,
  path: string,
  body?: unknown,
  contentType = 'application/json',
): Promise<T> {
  const headers: Record<string, string> = { Accept: 'application/json' };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  headers[CLIENT_HEADER] = tabClientId();
  // The control token, whenever this tab holds control: the server needs it on every request
  // that changes a drive (docs/api.md "Control and motion as built"); reads ignore it.
  Object.assign(headers, controlHeaders());
  // A FormData body (a file upload) gets its multipart/form-data type, with the boundary,
  // from the browser.
  if (body !== undefined && !(body instanceof FormData)) headers['Content-Type'] = contentType;
  let res: Response;
  try {
    res = await fetch(API_BASE + path, {
      method,
      headers,
      body: body === undefined ? null : body instanceof FormData || typeof body === 'string' ? body : JSON.stringify(body),
    });
  } catch {
    throw new ApiError(action, 0, {
      error: 'NetworkError',
      message: 'the servodesk server did not answer',
      hint: 'check that "servodesk serve" is still running and reachable from this browser',
    });
  }
  if (res.status === 204) return undefined as T;
  const text = await res.text();
  let payload: unknown = text;
  try {
    payload = text ? JSON.parse(text) : null;
  } catch {
    // Keep the text; normaliseErrorBody shows it if it is short.
  }
  // The login is gone (logged out elsewhere, idle time-out, ended by an administrator).
  if (res.status === 401) authLost('your session ended: log in again');
  if (!res.ok) throw new ApiError(action, res.status, normaliseErrorBody(res.status, res.statusText, payload));
  return payload as T;
}

const seg = encodeURIComponent;

/**
 * A file upload's body: multipart/form-data with the file in field `file`. The server takes
 * state-changing requests only as JSON, or as multipart where a file is uploaded
 * (docs/security.md): a text/plain body is what a page of another site could post.
 */
export function fileForm(filename: string, content: BlobPart): FormData {
  const form = new FormData();
  form.append('file', new Blob([content]), filename);
  return form;
}

export const api = {
  health: () => request<Health>('Check the server', 'GET', '/health'),
  profiles: () => request<ProfileSummary[]>('Load the drive profiles', 'GET', '/profiles'),
  scan: (req: ScanRequest) => request<ScanResult>('Scan the bus', 'POST', '/bus/scan', req),
  dcpIdentify: (req: DcpIdentifyRequest) =>
    request<DcpIdentifyResult>(`Search ${req.nic} for PROFINET devices`, 'POST', '/dcp/identify', req),
  dcpSet: (req: DcpSetRequest) => request<DcpDone>(`Set ${req.mac}`, 'POST', '/dcp/set', req),
  dcpSignal: (nic: string, mac: string) =>
    request<DcpDone>(`Flash the LED of ${mac}`, 'POST', '/dcp/signal', { nic, mac }),
  dcpReset: (nic: string, mac: string, mode: 2 | 8) =>
    request<DcpDone>(`Reset ${mac} to factory`, 'POST', '/dcp/reset', { nic, mac, mode }),
  sessions: () => request<SessionInfo[]>('List the sessions', 'GET', '/sessions'),
  openSession: (req: SessionRequest) =>
    request<SessionInfo>(`Open node ${req.node_id} on ${req.interface}`, 'POST', '/sessions', req),
  session: (sid: string) => request<SessionInfo>(`Load session ${sid}`, 'GET', `/sessions/${seg(sid)}`),
  closeSession: (sid: string) => request<void>(`Close session ${sid}`, 'DELETE', `/sessions/${seg(sid)}`),
  readObject: (sid: string, addr: string) =>
    request<ObjectValue>(`Read ${addr}`, 'GET', `/sessions/${seg(sid)}/objects/${seg(addr)}`),
  writeObject: (sid: string, addr: string, body: ObjectWrite) =>
    request<ObjectValue>(`Write ${addr}`, 'PUT', `/sessions/${seg(sid)}/objects/${seg(addr)}`, body),
  profile: (id: string) => request<ProfileDetail>(`Load profile ${id}`, 'GET', `/profiles/${seg(id)}`),
  /** The session's profile: the family's with its increment units for the drive's encoder. */
  sessionProfile: (sid: string) =>
    request<ProfileDetail>(`Load the profile of session ${sid}`, 'GET', `/sessions/${seg(sid)}/profile`),
  /** The device description (EDS/DCF/ESI) as a download URL (GET, so a plain link works). */
  profileExportUrl: (id: string, format: DeviceDescriptionFormat) =>
    `${API_BASE}/profiles/${seg(id)}/export?format=${format}`,
  importProfile: (filename: string, profileId: string, text: string) =>
    request<ProfileSummary>(
      `Import ${filename}`,
      'POST',
      `/profiles/import?filename=${seg(filename)}&profile_id=${seg(profileId)}`,
      fileForm(filename, text),
    ),
  /** Read up to 512 objects; one failure does not stop the rest (answers in request order). */
  readMany: (sid: string, addresses: string[]) =>
    request<ReadResponse>(`Read ${addresses.length} objects`, 'POST', `/sessions/${seg(sid)}/read`, { addresses }),
  store: (sid: string) => request<StoreResult>('Save to EEPROM', 'POST', `/sessions/${seg(sid)}/store`, {}),
  restoreDefaults: (sid: string, body: RestoreDefaultsRequest) =>
    request<RestoreDefaultsResult>('Restore defaults', 'POST', `/sessions/${seg(sid)}/restore-defaults`, body),
  state: (sid: string) => request<DriveState>('Read the drive state', 'GET', `/sessions/${seg(sid)}/state`),
  command: (sid: string, command: StateCommand, label: string) =>
    request<DriveState>(label, 'POST', `/sessions/${seg(sid)}/state`, { command }),
};

// ---------------------------------------------------------------------------------------------
// Backups (issue 5) — docs/api.md "Backup, compare, restore (issue 5)". Appended by the
// Backup & restore page; everything above belongs to the shared client.
// ---------------------------------------------------------------------------------------------
// An import may stand anywhere at a module's top level (it is hoisted); it is kept here so
// this section stays one appended block.
import { CLIENT_HEADER, tabClientId } from '../lib/backupClientId';
import type {
  AuditEntry,
  BackupFile,
  BackupFormat,
  BackupInfo,
  BackupPatch,
  BackupRequest,
  CompareRequest,
  Comparison,
  Preflight,
  PreflightRequest,
  RestoreReport,
  RestoreRequest,
} from './types';

/** Query text from the set parameters only (`undefined`/null/'' are left out). */
function query(params: Record<string, string | number | null | undefined>): string {
  const parts = Object.entries(params)
    .filter(([, v]) => v !== undefined && v !== null && v !== '')
    .map(([k, v]) => `${encodeURIComponent(k)}=${encodeURIComponent(String(v))}`);
  return parts.length ? `?${parts.join('&')}` : '';
}

/** A downloaded file: its bytes and the name the server gave it. */
export interface DownloadedFile {
  blob: Blob;
  filename: string | null;
}

/** The file name of a Content-Disposition header (RFC 6266; filename* wins), or null. */
export function filenameFromDisposition(header: string | null): string | null {
  if (!header) return null;
  const star = /filename\*\s*=\s*(?:UTF-8|utf-8)?''([^;]+)/.exec(header);
  if (star?.[1]) {
    try {
      return decodeURIComponent(star[1].trim().replace(/^"|"$/g, ''));
    } catch {
      // Fall through to the plain form.
    }
  }
  const plain = /filename\s*=\s*("([^"]*)"|[^;]+)/.exec(header);
  const name = plain?.[2] ?? plain?.[1];
  return name ? name.trim() : null;
}

/**
 * GET a file with the same headers as every other request (token, client id), so a download
 * works on a server that requires a token, where a plain link would get 401.
 */
async function fetchFile(action: string, path: string): Promise<DownloadedFile> {
  const headers: Record<string, string> = { [CLIENT_HEADER]: tabClientId(), ...controlHeaders() };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  let res: Response;
  try {
    res = await fetch(API_BASE + path, { headers });
  } catch {
    throw new ApiError(action, 0, {
      error: 'NetworkError',
      message: 'the servodesk server did not answer',
      hint: 'check that "servodesk serve" is still running and reachable from this browser',
    });
  }
  if (!res.ok) {
    const text = await res.text();
    let payload: unknown = text;
    try {
      payload = text ? JSON.parse(text) : null;
    } catch {
      // Keep the text.
    }
    throw new ApiError(action, res.status, normaliseErrorBody(res.status, res.statusText, payload));
  }
  return { blob: await res.blob(), filename: filenameFromDisposition(res.headers.get('Content-Disposition')) };
}

export const backupApi = {
  /** Take a backup of the drive now; progress comes over the WebSocket (operation "backup"). */
  take: (sid: string, body: BackupRequest) =>
    request<BackupInfo>('Take a backup', 'POST', `/sessions/${seg(sid)}/backups`, body),
  /** Newest first; `drive` and `profile` filter (both optional). */
  list: (filter: { drive?: string | null; profile?: string | null }) =>
    request<BackupInfo[]>('List the backups', 'GET', `/backups${query({ drive: filter.drive, profile: filter.profile })}`),
  get: (bid: string) => request<BackupFile>(`Load backup ${bid}`, 'GET', `/backups/${seg(bid)}`),
  download: (bid: string, format: BackupFormat) =>
    fetchFile(`Download backup as ${format.toUpperCase()}`, `/backups/${seg(bid)}/download?format=${format}`),
  upload: (filename: string, text: string) =>
    request<BackupInfo>(`Upload ${filename}`, 'POST', `/backups/upload${query({ filename })}`, fileForm(filename, text)),
  patch: (bid: string, body: BackupPatch) =>
    request<BackupInfo>('Save the backup label and note', 'PATCH', `/backups/${seg(bid)}`, body),
  compare: (body: CompareRequest) => request<Comparison>('Compare', 'POST', '/compare', body),
  preflight: (sid: string, body: PreflightRequest) =>
    request<Preflight>('Check the restore (preflight)', 'POST', `/sessions/${seg(sid)}/restore/preflight`, body),
  restore: (sid: string, body: RestoreRequest) =>
    request<RestoreReport>(body.dry_run ? 'Dry-run the restore' : 'Restore', 'POST', `/sessions/${seg(sid)}/restore`, body),
  report: (rid: string) => request<RestoreReport>(`Load restore report ${rid}`, 'GET', `/restores/${seg(rid)}`),
  resume: (rid: string) => request<RestoreReport>('Resume the restore', 'POST', `/restores/${seg(rid)}/resume`, {}),
  audit: (sid: string, limit = 100) =>
    request<AuditEntry[]>('Load the audit log', 'GET', `/audit/writes${query({ session: sid, limit })}`),
};

// ---------------------------------------------------------------------------------------------
// Operation and alarms (issue 4) — docs/api.md "Operation: control, motion, dead-man, homing,
// alarms". Appended by the Operation / Alarms / 3D view pages.
// ---------------------------------------------------------------------------------------------
import type {
  Alarms,
  Control,
  ControlAction,
  CyclicRequest,
  HomingMethod,
  HomingPlan,
  HomingRequest,
  HomingStatus,
  JogRequest,
  Limits,
  MotionStatus,
  MoveRequest,
  TorqueRequest,
  VelocityRequest,
  ViewerInfo,
} from './types';

const CONTROL_LABELS: Record<ControlAction, string> = {
  take: 'Take control',
  release: 'Release control',
  force_take: 'Force-take control',
};

export const operationApi = {
  control: (sid: string) => request<Control>('Read who holds control', 'GET', `/sessions/${seg(sid)}/control`),
  setControl: (sid: string, action: ControlAction, confirm = false) =>
    request<Control>(CONTROL_LABELS[action], 'POST', `/sessions/${seg(sid)}/control`, { action, confirm }),
  jog: (sid: string, body: JogRequest) => request<MotionStatus>('Jog', 'POST', `/sessions/${seg(sid)}/motion/jog`, body),
  move: (sid: string, body: MoveRequest) =>
    request<MotionStatus>(`${body.mode === 'relative' ? 'Relative' : 'Absolute'} move`, 'POST', `/sessions/${seg(sid)}/motion/move`, body),
  velocity: (sid: string, body: VelocityRequest) =>
    request<MotionStatus>('Profile velocity', 'POST', `/sessions/${seg(sid)}/motion/velocity`, body),
  torque: (sid: string, body: TorqueRequest) =>
    request<MotionStatus>('Profile torque', 'POST', `/sessions/${seg(sid)}/motion/torque`, body),
  cyclic: (sid: string, body: CyclicRequest) =>
    request<MotionStatus>(`Cyclic ${body.mode}`, 'POST', `/sessions/${seg(sid)}/motion/cyclic`, body),
  halt: (sid: string) => request<MotionStatus>('Halt', 'POST', `/sessions/${seg(sid)}/motion/halt`, {}),
  quickStop: (sid: string) => request<MotionStatus>('Quick stop', 'POST', `/sessions/${seg(sid)}/motion/stop`, {}),
  motion: (sid: string) => request<MotionStatus>('Read the motion', 'GET', `/sessions/${seg(sid)}/motion`),
  limits: (sid: string) => request<Limits>('Read the limits', 'GET', `/sessions/${seg(sid)}/limits`),
  homingMethods: (sid: string) =>
    request<HomingMethod[]>('Load the homing methods', 'GET', `/sessions/${seg(sid)}/homing/methods`),
  startHoming: (sid: string, body: HomingRequest) =>
    request<HomingStatus>(`Start homing (method ${body.method})`, 'POST', `/sessions/${seg(sid)}/homing`, body),
  homing: (sid: string) => request<HomingStatus>('Read the homing status', 'GET', `/sessions/${seg(sid)}/homing`),
  homingPlan: (sid: string, req: HomingRequest) =>
    request<HomingPlan>(
      'Estimate the homing run',
      'GET',
      `/sessions/${seg(sid)}/homing/plan${query({
        method: req.method,
        speed_switch: req.speed_switch,
        speed_zero: req.speed_zero,
        acceleration: req.acceleration,
        max_travel: req.max_travel,
        timeout_s: req.timeout_s,
      })}`,
    ),
  alarms: (sid: string) => request<Alarms>('Read the alarms', 'GET', `/sessions/${seg(sid)}/alarms`),
  resetAlarms: (sid: string) => request<Alarms>('Fault reset', 'POST', `/sessions/${seg(sid)}/alarms/reset`, {}),
  clearAlarmHistory: (sid: string) =>
    request<Alarms>('Clear the alarm history', 'POST', `/sessions/${seg(sid)}/alarms/clear-history`, { confirm: true }),
  viewer: () => request<ViewerInfo>('Ask for the 3D viewer', 'GET', '/viewer'),
};

// ---------------------------------------------------------------------------------------------
// Audit log (issue 45) — docs/api.md "Audit log".
// ---------------------------------------------------------------------------------------------
import type { AuditFilter, AuditRecord, AuditVerdict } from './types';

export const auditApi = {
  /** Newest first, every given filter applied. */
  list: (f: AuditFilter) =>
    request<AuditRecord[]>(
      'Load the audit log',
      'GET',
      `/audit${query({
        category: f.category,
        user: f.user,
        drive: f.drive,
        since: f.since,
        until: f.until,
        before: f.before,
        limit: f.limit,
      })}`,
    ),
  verify: () => request<AuditVerdict>('Verify the audit log', 'GET', '/audit/verify'),
  export: (format: 'jsonl' | 'csv', since?: string | null) =>
    fetchFile(`Export the audit log as ${format.toUpperCase()}`, `/audit/export${query({ format, since })}`),
};
