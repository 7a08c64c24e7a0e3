/**
 * Typed endpoint functions of /api/v1 (docs/api.md): sessions, objects, profiles, the bus
 * scan, DCP, backups, operation, alarms and the audit log.
 *
 * Each is one call of the one fetch wrapper, {@link apiRequest} in `./http`, whose path,
 * parameters, body and answer are typed from the generated `./schema.ts` (docs/architecture.md
 * "Wire contract"). The first argument says what the user was doing, for the error.
 */
import { apiDownload, apiRequest, apiUrl, fileForm, serverDefaults } from './http';
import type { components } from './schema';
import type {
  AuditFilter,
  BackupInfo,
  BackupFormat,
  BackupPatch,
  BackupRequest,
  CompareRequest,
  Comparison,
  ControlAction,
  CyclicRequest,
  DcpIdentifyRequest,
  DcpSetRequest,
  DeviceDescriptionFormat,
  HomingRequest,
  JogRequest,
  MoveRequest,
  ObjectWrite,
  PlantBackupReport,
  PlantBackupRequest,
  Preflight,
  PreflightRequest,
  RestoreDefaultsRequest,
  RestoreReport,
  RestoreRequest,
  ScanRequest,
  SessionRequest,
  StateCommand,
  TorqueRequest,
  VelocityRequest,
} from './types';

type S = components['schemas'];

// The error, the download and the upload form live with the wrapper; these re-exports keep the
// pages' imports of this module as they were.
export {
  API_BASE,
  ApiError,
  type DownloadedFile,
  fileForm,
  filenameFromDisposition,
  normaliseErrorBody,
} from './http';

export const api = {
  health: () => apiRequest('Check the server', 'GET', '/health'),
  profiles: () => apiRequest('Load the drive profiles', 'GET', '/profiles'),
  scan: (req: ScanRequest) => apiRequest('Scan the bus', 'POST', '/bus/scan', { body: req }),
  dcpIdentify: (req: DcpIdentifyRequest) =>
    apiRequest(`Search ${req.nic} for PROFINET devices`, 'POST', '/dcp/identify', {
      body: serverDefaults<S['DcpIdentifyRequest'], 'timeout'>(req),
    }),
  dcpSet: (req: DcpSetRequest) => apiRequest(`Set ${req.mac}`, 'POST', '/dcp/set', { body: serverDefaults<S['DcpSetRequest'], 'permanent'>(req) }),
  dcpSignal: (nic: string, mac: string) =>
    apiRequest(`Flash the LED of ${mac}`, 'POST', '/dcp/signal', { body: { nic, mac } }),
  dcpReset: (nic: string, mac: string, mode: 2 | 8) =>
    apiRequest(`Reset ${mac} to factory`, 'POST', '/dcp/reset', { body: { nic, mac, mode } }),
  sessions: () => apiRequest('List the sessions', 'GET', '/sessions'),
  status: () => apiRequest('Read the buses\' status', 'GET', '/status'),
  openSession: (req: SessionRequest) =>
    apiRequest(`Open node ${req.node_id} on ${req.interface}`, 'POST', '/sessions', { body: req }),
  session: (sid: string) => apiRequest(`Load session ${sid}`, 'GET', '/sessions/{sid}', { params: { sid } }),
  closeSession: (sid: string) => apiRequest(`Close session ${sid}`, 'DELETE', '/sessions/{sid}', { params: { sid } }),
  readObject: (sid: string, address: string) =>
    apiRequest(`Read ${address}`, 'GET', '/sessions/{sid}/objects/{address}', { params: { sid, address } }),
  writeObject: (sid: string, address: string, body: ObjectWrite) =>
    apiRequest(`Write ${address}`, 'PUT', '/sessions/{sid}/objects/{address}', { params: { sid, address }, body }),
  profile: (profile_id: string) =>
    apiRequest(`Load profile ${profile_id}`, 'GET', '/profiles/{profile_id}', { params: { profile_id } }),
  /** The session's profile: the family's with its increment units for the drive's encoder. */
  sessionProfile: (sid: string) =>
    apiRequest(`Load the profile of session ${sid}`, 'GET', '/sessions/{sid}/profile', { params: { sid } }),
  /** The device description (EDS/DCF/ESI) as a download URL (GET, so a plain link works). */
  profileExportUrl: (profile_id: string, format: DeviceDescriptionFormat) =>
    apiUrl('/profiles/{profile_id}/export', { params: { profile_id }, query: { format } }),
  importProfile: (filename: string, profileId: string, text: string) =>
    apiRequest(`Import ${filename}`, 'POST', '/profiles/import', {
      query: { filename, profile_id: profileId },
      body: fileForm(filename, text),
    }),
  /** Read up to 512 objects; one failure does not stop the rest (answers in request order). */
  readMany: (sid: string, addresses: string[]) =>
    apiRequest(`Read ${addresses.length} objects`, 'POST', '/sessions/{sid}/read', { params: { sid }, body: { addresses } }),
  store: (sid: string) => apiRequest('Save to EEPROM', 'POST', '/sessions/{sid}/store', { params: { sid } }),
  restoreDefaults: (sid: string, body: RestoreDefaultsRequest) =>
    apiRequest('Restore defaults', 'POST', '/sessions/{sid}/restore-defaults', { params: { sid }, body }),
  state: (sid: string) => apiRequest('Read the drive state', 'GET', '/sessions/{sid}/state', { params: { sid } }),
  command: (sid: string, command: StateCommand, label: string) =>
    apiRequest(label, 'POST', '/sessions/{sid}/state', { params: { sid }, body: { command } }),
};

// ---------------------------------------------------------------------------------------------
// Backups (issue 5) — docs/api.md "Backup, compare, restore (issue 5)". Their lists of
// unreadable objects are always sent, which the schema cannot say (`Always` in ./types).
// ---------------------------------------------------------------------------------------------

export const backupApi = {
  /** Take a backup of the drive now; progress comes over the WebSocket (operation "backup"). */
  take: (sid: string, body: BackupRequest) =>
    apiRequest('Take a backup', 'POST', '/sessions/{sid}/backups', { params: { sid }, body }) as Promise<BackupInfo>,
  /** A backup of every open drive (or of `sessions`), the drives read at once. */
  plant: (body: PlantBackupRequest) =>
    apiRequest('Back up every drive', 'POST', '/backups/plant', { body }) as Promise<PlantBackupReport>,
  /** Newest first; `drive` and `profile` filter (both optional). */
  list: (filter: { drive?: string | null; profile?: string | null }) =>
    apiRequest('List the backups', 'GET', '/backups', { query: { drive: filter.drive, profile: filter.profile } }) as Promise<BackupInfo[]>,
  get: (bid: string) => apiRequest(`Load backup ${bid}`, 'GET', '/backups/{bid}', { params: { bid } }),
  download: (bid: string, format: BackupFormat) =>
    apiDownload(`Download backup as ${format.toUpperCase()}`, '/backups/{bid}/download', {
      params: { bid },
      query: { format },
    }),
  upload: (filename: string, text: string) =>
    apiRequest(`Upload ${filename}`, 'POST', '/backups/upload', { query: { filename }, body: fileForm(filename, text) }) as Promise<BackupInfo>,
  patch: (bid: string, body: BackupPatch) =>
    apiRequest('Save the backup label and note', 'PATCH', '/backups/{bid}', { params: { bid }, body }) as Promise<BackupInfo>,
  // A defaults source may leave out node_id (the server's default): ServerDefaults one level down.
  compare: (body: CompareRequest) => apiRequest('Compare', 'POST', '/compare', { body: body as S['CompareRequest'] }) as Promise<Comparison>,
  preflight: (sid: string, body: PreflightRequest) =>
    apiRequest('Check the restore (preflight)', 'POST', '/sessions/{sid}/restore/preflight', { params: { sid }, body }) as Promise<Preflight>,
  restore: (sid: string, body: RestoreRequest) =>
    apiRequest(body.dry_run ? 'Dry-run the restore' : 'Restore', 'POST', '/sessions/{sid}/restore', { params: { sid }, body }) as Promise<RestoreReport>,
  report: (rid: string) => apiRequest(`Load restore report ${rid}`, 'GET', '/restores/{rid}', { params: { rid } }) as Promise<RestoreReport>,
  resume: (rid: string) => apiRequest('Resume the restore', 'POST', '/restores/{rid}/resume', { params: { rid } }) as Promise<RestoreReport>,
  audit: (sid: string, limit = 100) =>
    apiRequest('Load the audit log', 'GET', '/audit/writes', { query: { session: sid, limit } }),
};

// ---------------------------------------------------------------------------------------------
// Operation and alarms (issue 4) — docs/api.md "Operation: control, motion, dead-man, homing,
// alarms".
// ---------------------------------------------------------------------------------------------

const CONTROL_LABELS: Record<ControlAction, string> = {
  take: 'Take control',
  release: 'Release control',
  force_take: 'Force-take control',
};

export const operationApi = {
  control: (sid: string) => apiRequest('Read who holds control', 'GET', '/sessions/{sid}/control', { params: { sid } }),
  setControl: (sid: string, action: ControlAction, confirm = false) =>
    apiRequest(CONTROL_LABELS[action], 'POST', '/sessions/{sid}/control', { params: { sid }, body: { action, confirm } }),
  jog: (sid: string, body: JogRequest) => apiRequest('Jog', 'POST', '/sessions/{sid}/motion/jog', { params: { sid }, body }),
  move: (sid: string, body: MoveRequest) =>
    apiRequest(`${body.mode === 'relative' ? 'Relative' : 'Absolute'} move`, 'POST', '/sessions/{sid}/motion/move', {
      params: { sid },
      body: serverDefaults<S['MoveRequest'], 'immediate'>(body),
    }),
  velocity: (sid: string, body: VelocityRequest) =>
    apiRequest('Profile velocity', 'POST', '/sessions/{sid}/motion/velocity', { params: { sid }, body }),
  torque: (sid: string, body: TorqueRequest) =>
    apiRequest('Profile torque', 'POST', '/sessions/{sid}/motion/torque', { params: { sid }, body }),
  cyclic: (sid: string, body: CyclicRequest) =>
    apiRequest(`Cyclic ${body.mode}`, 'POST', '/sessions/{sid}/motion/cyclic', { params: { sid }, body }),
  halt: (sid: string) => apiRequest('Halt', 'POST', '/sessions/{sid}/motion/halt', { params: { sid }, body: {} }),
  quickStop: (sid: string) => apiRequest('Quick stop', 'POST', '/sessions/{sid}/motion/stop', { params: { sid }, body: {} }),
  motion: (sid: string) => apiRequest('Read the motion', 'GET', '/sessions/{sid}/motion', { params: { sid } }),
  limits: (sid: string) => apiRequest('Read the limits', 'GET', '/sessions/{sid}/limits', { params: { sid } }),
  homingMethods: (sid: string) =>
    apiRequest('Load the homing methods', 'GET', '/sessions/{sid}/homing/methods', { params: { sid } }),
  startHoming: (sid: string, body: HomingRequest) =>
    apiRequest(`Start homing (method ${body.method})`, 'POST', '/sessions/{sid}/homing', { params: { sid }, body }),
  homing: (sid: string) => apiRequest('Read the homing status', 'GET', '/sessions/{sid}/homing', { params: { sid } }),
  homingPlan: (sid: string, req: HomingRequest) =>
    apiRequest('Estimate the homing run', 'GET', '/sessions/{sid}/homing/plan', {
      params: { sid },
      query: {
        method: req.method,
        speed_switch: req.speed_switch,
        speed_zero: req.speed_zero,
        acceleration: req.acceleration,
        max_travel: req.max_travel,
        timeout_s: req.timeout_s,
      },
    }),
  alarms: (sid: string) => apiRequest('Read the alarms', 'GET', '/sessions/{sid}/alarms', { params: { sid } }),
  resetAlarms: (sid: string) => apiRequest('Fault reset', 'POST', '/sessions/{sid}/alarms/reset', { params: { sid } }),
  clearAlarmHistory: (sid: string) =>
    apiRequest('Clear the alarm history', 'POST', '/sessions/{sid}/alarms/clear-history', {
      params: { sid },
      body: { confirm: true },
    }),
  viewer: () => apiRequest('Ask for the 3D viewer', 'GET', '/viewer'),
};

// ---------------------------------------------------------------------------------------------
// Audit log (issue 45) — docs/api.md "Audit log".
// ---------------------------------------------------------------------------------------------

export const auditApi = {
  /** Newest first, every given filter applied. */
  list: (f: AuditFilter) =>
    apiRequest('Load the audit log', 'GET', '/audit', {
      query: {
        category: f.category,
        user: f.user,
        drive: f.drive,
        since: f.since,
        until: f.until,
        before: f.before,
        limit: f.limit,
      },
    }),
  verify: () => apiRequest('Verify the audit log', 'GET', '/audit/verify'),
  export: (format: 'jsonl' | 'csv', since?: string | null) =>
    apiDownload(`Export the audit log as ${format.toUpperCase()}`, '/audit/export', { query: { format, since } }),
};
