/**
 * REST shapes of the servodesk API v1: aliases of the generated `./schema.ts` (npm run gen:api
 * from backend/openapi.json; docs/architecture.md "Wire contract"), so that a change of the
 * backend's models shows here as a type error rather than at run time.
 *
 * Written here, and only where the UI knows more than the schema: `Always` for lists the
 * server always sends (a pydantic default_factory leaves them optional in the schema),
 * `ServerDefaults` for request fields the UI leaves to the server's default, narrower unions
 * the UI switches on, and the request bodies the UI builds (the wrapper checks them against
 * the schema's).
 */
import type { Always, ServerDefaults } from './http';
import type { components, paths } from './schema';

type S = components['schemas'];

/** The `format` query parameter of a download route. */
type ExportFormat<P extends keyof paths> = paths[P] extends { get: { parameters: { query?: infer Q } } }
  ? Q extends { format?: infer F }
    ? F
    : never
  : never;

export type ApiErrorBody = S['ErrorOut'];

export type Health = S['HealthOut'];

export type ProfileSummary = S['ProfileSummary'];

/** python-can interface names the backend accepts. */
export type BusInterface = Exclude<S['ScanRequest']['interface'], 'ethercat'>;

/** Every interface a session opens on: python-can's (CANopen), slmp for a CC-Link IE TSN
 * station reached by SLMP over UDP (channel host:port, node id = axis + 1), profinet for a
 * PROFIdrive drive reached by PNIO-CM record access over UDP (channel host[:port], node id =
 * DO-ID), and ethercat for an EtherCAT line (channel the network interface, node id = slave
 * position + 1). */
export type SessionInterface = S['SessionCreate']['interface'];

export type ScanRequest = S['ScanRequest'];

export type ScanNode = S['ScanNode'];

export type ScanResult = S['ScanOut'];

/** POST /dcp/identify: the PROFINET devices on a network interface (docs/profinet.md, DCP). */
export type DcpIdentifyRequest = ServerDefaults<S['DcpIdentifyRequest'], 'timeout'>;

export type DcpDevice = S['DcpDeviceOut'];

export type DcpIdentifyResult = S['DcpIdentifyOut'];

export type DcpSetRequest = ServerDefaults<S['DcpSetRequest'], 'permanent'>;

export type DcpDone = S['DcpDone'];

export type Identity = S['IdentityOut'];

export type SessionRequest = S['SessionCreate'];

export type SessionInfo = S['SessionInfo'];

/** GET /status: the status bar's numbers per bus (docs/api.md "Status"). */
export type BusStatus = S['BusStatusOut'];
export type StoreStatus = S['StoreStatusOut'];

export type SessionEncoder = S['EncoderOut'];

export type ObjectScalar = number | string | boolean;

export type ObjectValue = S['ObjectValueOut'];

export type ObjectWrite = S['WriteRequest'];

export type ErrorInfo = S['ErrorInfo'];

export type StatusBit = S['StatusBit'];

export type DriveState = S['DriveStateOut'];

export type StateCommand = S['StateCommand']['command'];

export type StateCommandRequest = S['StateCommand'];

/** One object of a profile's dictionary (GET /profiles/{id} `object_list`). */
export type ObjectInfo = S['ObjectInfo'];

export type GroupInfo = S['GroupInfo'];

export type QuirkInfo = S['QuirkInfo'];

/** An object of the profile's `network:` section: its address as `object_list` names it. */
export type NetworkObjectInfo = S['NetworkObjectInfo'];

export type NetworkRuleInfo = S['NetworkRuleInfo'];

export type NetworkLedInfo = S['NetworkLedInfo'];

/** How the family is addressed on its fieldbus (profile `network:`, docs/profiles.md). */
export type NetworkInfo = S['NetworkInfo'];

/** GET /profiles/{id}. */
export type ProfileDetail = S['ProfileDetail'];

/** One answer of POST /sessions/{sid}/read: the value, or why that one address failed. */
export type ReadItem = S['ReadResults']['results'][number];

export type ReadRequest = S['ReadRequest'];

export type ReadResponse = S['ReadResults'];

export type StoreResult = S['StoreResult'];

export type RestoreDefaultsRequest = S['RestoreDefaultsRequest'];

export type RestoreDefaultsResult = S['MessageOut'];

export type DeviceDescriptionFormat = NonNullable<ExportFormat<'/api/v1/profiles/{profile_id}/export'>>;

// ---------------------------------------------------------------------------------------------
// Backups (issue 5) — docs/api.md "Backup, compare, restore (issue 5)". Appended by the
// Backup & restore page; everything above belongs to the other pages.
// ---------------------------------------------------------------------------------------------

/** Where a drive is on the bus when its backup was taken. */
export type BackupBus = S['BackupBus'];

/** An object the drive refused when a set was read: the set lacks it (issue 48). */
export type UnreadableEntry = S['UnreadableOut'];

/** One stored backup (the file's metadata; the file itself never changes). */
export type BackupInfo = Always<S['BackupInfo'], 'unreadable'>;

export type BackupRequest = S['BackupCreate'];

/** POST /backups/plant: every open drive (or those named) backed up at once. */
export type PlantBackupRequest = S['PlantBackupCreate'];
export type PlantBackupReport = S['PlantBackupReport'];

export type BackupPatch = S['BackupPatch'];

export type BackupFileEntry = S['BackupEntryOut'];

/** GET /backups/{bid}: the JSON file's content. */
export type BackupFile = S['BackupFile'];

export type BackupFormat = NonNullable<ExportFormat<'/api/v1/backups/{bid}/download'>>;

/** One side of a comparison. */
/** `node_id` of a defaults source has a server default (1). */
export type CompareSource = S['SourceDrive'] | S['SourceBackup'] | ServerDefaults<S['SourceDefaults'], 'node_id'>;

export type CompareRequest = Omit<S['CompareRequest'], 'a' | 'b'> & { a: CompareSource; b: CompareSource };

/**
 * "changed" / "only_a" / "only_b" per the contract; with `all: true` the server may also list
 * equal entries, under a kind the contract does not name yet ("equal" or "same").
 */
export type DifferenceKind = S['DifferenceOut']['kind'];

export type Difference = S['DifferenceOut'];

export type Comparison = Always<S['Comparison'], 'a_unreadable' | 'b_unreadable'>;

export type PreflightRequest = S['PreflightRequest'];

export type PreflightProblem = S['ProblemOut'];

export type NameMapping = S['MappingOut'];

export type Preflight = Always<S['PreflightOut'], 'unreadable'>;

export type RestoreRequest = S['RestoreRequest'];

export type RestoreItemStatus = S['RestoreItemOut']['status'];

export type RestoreItem = S['RestoreItemOut'];

export type RestoreCounts = S['RestoreCounts'];

export type RestoreReport = Always<S['RestoreReport'], 'unreadable'>;

export type AuditEntry = S['AuditEntry'];

// ---------------------------------------------------------------------------------------------
// Operation and alarms (issue 4) — docs/api.md "Operation: control, motion, dead-man, homing,
// alarms". Appended by the Operation / Alarms / 3D view pages; shapes follow the backend
// (api/schemas_motion.py, schemas_homing.py), which adds a few fields to the contract (marked "backend addition").
// ---------------------------------------------------------------------------------------------

export type ControlAction = S['ControlRequest']['action'];

/** GET/POST /control; the WebSocket's control event carries only session, owner, since and you. */
export type Control = Omit<S['ControlOut'], 'bound' | 'orphaned'> & Partial<Pick<S['ControlOut'], 'bound' | 'orphaned'>>;

export type ControlProtection = S['ProtectionOut'];

export type JogRequest = S['JogRequest'];

export type MoveRequest = ServerDefaults<S['MoveRequest'], 'immediate'>;

export type VelocityRequest = S['VelocityRequest'];

export type TorqueRequest = S['TorqueRequest'];

export type CyclicMode = S['CyclicMotionRequest']['mode'];

export type CyclicRequest = S['CyclicMotionRequest'];

export type MotionKind = NonNullable<S['MotionStatusOut']['kind']>;

export type MotionStatus = S['MotionStatusOut'];

export type UnitInfo = S['UnitOut'];

export type Limits = S['LimitsOut'];

export type HomingSignal = 'home_switch' | 'limit_negative' | 'limit_positive' | 'index';

export type HomingMethod = S['HomingMethodOut'];

export type HomingRequest = S['HomingRequest'];

/** One part of a homing run at one speed (domain/homing.py). */
export type HomingPhase = S['HomingPhaseOut'];

export type HomingEstimate = S['HomingEstimateOut'];

/** What a run is expected to take: GET /homing/plan, and part of every run. */
export type HomingPlan = S['HomingPlanOut'];

/** How a run ended (running while it lasts): the motion's end, not only the statusword. */
export type HomingOutcome = S['HomingRunOut']['outcome'];

export type HomingRun = S['HomingRunOut'];

export type HomingBits = S['HomingBits'];

export type HomingState = S['HomingStatus']['state'];

export type HomingStatus = S['HomingStatus'];

export type EmcyLogEntry = S['EmcyLogEntry'];

export type AlarmHistoryEntry = S['AlarmHistoryEntry'];

export type Alarms = S['AlarmsOut'];

/** GET /viewer: the viser 3D viewer. */
/** The UI's reading of GET /viewer: every field optional, and the `message`/`reason` an older
 * server sent; lib/viewer.ts falls back on them. */
export interface ViewerInfo {
  enabled: boolean;
  url: string | null;
  port: number | null;
  /** Backend addition: the viewer process is up. */
  running?: boolean;
  /** Backend addition: why it is not running, when it failed. */
  error?: string | null;
  /** Why it is disabled, when the backend says. */
  message?: string | null;
  reason?: string | null;
}

// ---------------------------------------------------------------------------------------------
// PDO mapping and cyclic process data (issue 6) — docs/pdo.md "REST": the answers are the
// schema's (api/schemas_pdo.py); the request bodies are the UI's (the wrapper checks them).
// ---------------------------------------------------------------------------------------------

/** rx: master -> drive (RPDO, setpoint telegram); tx: drive -> master (TPDO, actual values). */
export type PdoDirection = S['PdoOut']['direction'];

/** How a family maps process data (profile `pdo.kind`, docs/pdo.md "Families"). */
export type PdoKind = S['PdoView']['kind'];

export type PdoRules = S['PdoRulesOut'];

/** One telegram of the family (004 §20.3): a fixed one's layout cannot change. */
export type PdoTelegramInfo = S['PdoTelegramOut'];

/** A reason a mapping is refused, shown next to the PDO / entry / field it names (also the
 * `problems` of a refused mapping's 422). */
export type PdoProblem = S['PdoProblemOut'];

export type PdoEntryOut = S['PdoEntryOut'];

export type PdoOut = S['PdoOut'];

// A type literal, not an interface: it must fit the schema's `{ [key: string]: number[] }`.
export type PdoAssignment = {
  rx: number[];
  tx: number[];
};

/** GET /pdo and the `view` of validate / templates / apply. */
export type PdoView = S['PdoView'];

/** One mapping entry as the API takes it (index 0: LECSN Reserved padding). */
export interface PdoLayoutEntry {
  index: number;
  subindex: number;
  bits: number;
}

export interface PdoLayoutPdo {
  direction: PdoDirection;
  number: number;
  entries: Array<string | PdoLayoutEntry>;
  cob_id?: number;
  enabled?: boolean;
  rtr_allowed?: boolean;
  transmission_type?: number;
  inhibit_time?: number;
  event_timer?: number;
  sync_start?: number;
}

/** The body of validate / plan / apply: PDOs left out keep their current configuration. */
export interface PdoLayout {
  pdos: PdoLayoutPdo[];
  assignment?: PdoAssignment;
  telegram?: number;
}

export type MappableObject = S['MappableObject'];

export type PdoMappable = S['PdoMappable'];

export type PdoTemplate = S['PdoTemplateOut'];

export type PdoValidation = S['PdoValidation'];

export type PdoStep = S['PdoStepOut'];

export type PdoPlan = S['PdoPlan'];

/** The UI's body of apply (the wrapper checks it against the schema's ApplyRequest). */
export interface PdoApplyRequest extends PdoLayout {
  dry_run: boolean;
}

export type PdoApplyReport = S['PdoApplyReport'];

export type PdoRate = S['PdoRate'];

/** One change that makes a silent event-driven TPDO send: a PDO change (needs control). */
export type PdoIdleFix = S['PdoIdleFix'];

export type PdoIdle = S['PdoIdle'];

/** One mapped object's latest value from the cyclic data (also in the WebSocket's `pdo`
 * messages: services/cyclic.py values_view). */
export type PdoLiveValue = S['PdoLiveValue'];

/** What the cycles say about an EtherCAT line (null on CAN). */
export type PdoLinkHealth = S['PdoLinkHealth'];

/** GET/POST/DELETE /pdo/cyclic and PUT /pdo/cyclic/outputs: keys with `?` are in some
 * answers only (api/schemas_pdo.py). */
export type PdoCyclicStatus = S['PdoCyclicStatus'];

export type PdoCyclicRequest = S['PdoCyclicRequest'];

export type PdoExportFormat = NonNullable<ExportFormat<'/api/v1/sessions/{sid}/pdo/export'>>;

// --- Audit log (issue 45; docs/api.md "Audit log") ------------------------------------------

export type AuditCategory = S['AuditRecord']['category'];

/** One audit record (GET /audit), with its place in the hash chain. */
export type AuditRecord = S['AuditRecord'];

export interface AuditFilter {
  category?: AuditCategory | null;
  user?: string | null;
  drive?: string | null;
  /** ISO 8601 (UTC). */
  since?: string | null;
  until?: string | null;
  /** Only records older than this seq (the next page). */
  before?: number | null;
  limit?: number;
}

/** GET /audit/verify: the chain recomputed. */
export type AuditVerdict = S['AuditVerdict'];
