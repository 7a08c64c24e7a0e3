/**
 * REST shapes of the servodesk API v1: aliases of the generated `./schema.ts` (npm run gen:api
 * from backend/openapi.json; docs/architecture.md "Wire contract"), so that a change of the
 * backend's models shows here as a type error rather than at run time.
 *
 * Written here, and only where the UI knows more than the schema: `Always` for lists the
 * server always sends (a pydantic default_factory leaves them optional in the schema),
 * `ServerDefaults` for request fields the UI leaves to the server's default, narrower unions
 * the UI switches on, the request bodies the UI builds (the wrapper checks them against the
 * schema's), and the answers of routes that still return `dict[str, Any]` (PDO), until the
 * backend gives them response models (issue 51 item 1).
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
// (api/schemas.py), which adds a few fields to the contract (marked "backend addition").
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
// PDO mapping and cyclic process data (issue 6) — docs/pdo.md "REST". Appended by the PDO
// mapping page; everything above belongs to the shared types.
// ---------------------------------------------------------------------------------------------

/** rx: master -> drive (RPDO, setpoint telegram); tx: drive -> master (TPDO, actual values). */
export type PdoDirection = 'rx' | 'tx';

/** How a family maps process data (profile `pdo.kind`, docs/pdo.md "Families"). */
export type PdoKind = 'canopen' | 'ethercat' | 'fixed' | 'telegram';

export interface PdoRules {
  max_entries: number;
  max_bits: number;
  /** Bytes per direction over all active PDOs (HIWIN 000 §2.2: 40), when the family has a limit. */
  max_bytes: number | null;
  /** "preop" or "fixed". */
  mapping_state: string;
  section: string | null;
  rpdo_count: number;
  tpdo_count: number;
  /** The family's PROFIdrive telegrams (empty for the other kinds). */
  telegrams?: PdoTelegramInfo[];
}

/** One telegram of the family (004 §20.3): a fixed one's layout cannot change. */
export interface PdoTelegramInfo {
  number: number;
  name: string;
  /** IO data per direction; a variable mapping must fill it exactly. */
  bytes: number;
  max_entries: number;
  variable: boolean;
}

/** A reason a mapping is refused, shown next to the PDO / entry / field it names. */
export interface PdoProblem {
  message: string;
  /** Pdo name ("TPDO2"), null for the whole mapping. */
  pdo: string | null;
  /** 0-based entry position in that PDO. */
  entry: number | null;
  /** "entries", "cob_id", "transmission_type", "assignment", "telegram", ... */
  field: string | null;
  section: string | null;
}

export interface PdoEntryOut {
  index: number;
  subindex: number;
  bits: number;
  raw_hex: string;
  /** "0x6064:00"; null for padding. */
  address: string | null;
  name: string;
  /** Type name ("INTEGER32"); the backend sends the CiA 306 number (4) today. */
  data_type: string | number | null;
  unit: string | null;
  offset_bits: number;
  offset_byte: number;
  padding: boolean;
}

export interface PdoOut {
  direction: PdoDirection;
  number: number;
  name: string;
  mapping_index: number;
  /** Null: the family has no communication parameters (ethercat, fixed, telegram). */
  comm_index: number | null;
  cob_id: number | null;
  cob_id_hex: string | null;
  enabled: boolean | null;
  rtr_allowed: boolean | null;
  transmission_type: number | null;
  transmission_text: string | null;
  inhibit_time: number | null;
  inhibit_time_ms: number | null;
  event_timer: number | null;
  sync_start: number | null;
  /** On the bus: enabled (canopen), assigned (ethercat), always (fixed, telegram). */
  active: boolean;
  bits: number;
  max_bits: number;
  bytes: number;
  frame_length: number;
  entries: PdoEntryOut[];
}

// A type literal, not an interface: it must fit the schema's `{ [key: string]: number[] }`.
export type PdoAssignment = {
  rx: number[];
  tx: number[];
};

/** GET /pdo and the `view` of validate / templates / apply. */
export interface PdoView {
  kind: PdoKind;
  /** "little" (CiA 301) or "big" (LECSN telegrams, 004 §20.1.2). */
  byte_order: string;
  rules: PdoRules;
  pdos: PdoOut[];
  assignment: PdoAssignment | null;
  telegram: number | null;
  nmt_state: string | null;
  /** Why the session's link does not write the mapping (PROFINET: the IO controller's), or
   * null. The layout can still be edited, checked and exported. */
  apply_unavailable?: string | null;
  problems: PdoProblem[];
}

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

export interface MappableObject {
  address: string;
  index: number;
  subindex: number;
  name: string;
  /** Type name ("INTEGER32"); the backend sends the CiA 306 number (4) today. */
  data_type: string | number;
  bits: number;
  unit: string | null;
  direction: PdoDirection | 'both';
}

export interface PdoMappable {
  rx: MappableObject[];
  tx: MappableObject[];
}

export interface PdoTemplate {
  id: string;
  name: string;
  description: string | null;
  section: string | null;
}

export interface PdoValidation {
  ok: boolean;
  problems: PdoProblem[];
  view: PdoView;
}

export interface PdoStep {
  kind: 'write' | 'nmt';
  address: string | null;
  value: number;
  value_hex: string | null;
  /** nmt: "preop" | "start" | "stop". */
  command: string | null;
  why: string;
}

export interface PdoPlan {
  steps: PdoStep[];
  touched: string[];
}

/** The UI's body of apply (the wrapper checks it against the schema's ApplyRequest). */
export interface PdoApplyRequest extends PdoLayout {
  dry_run: boolean;
}

export interface PdoApplyReport {
  ok: boolean;
  dry_run: boolean;
  steps: PdoStep[];
  /** Steps done before the end (all of them when ok). */
  done: number;
  duration_s: number;
  verified: boolean;
  rolled_back: boolean;
  error: string | null;
  failed_step: PdoStep | null;
  /** The drive after the run; null when it could not be read (link lost). */
  view: PdoView | null;
  /** Backend addition: names of the PDOs the plan changed. */
  touched?: string[];
  /** Backend addition: why the previous mapping could not be put back. */
  rollback_error?: string | null;
}

export interface PdoRate {
  name: string;
  cob_id: number | null;
  /** Backend addition. */
  cob_id_hex?: string;
  count: number;
  /** Null for RX PDOs (the session sends them with each SYNC). */
  rate_hz: number | null;
  /** Backend addition: frames that could not be decoded. */
  errors?: number;
  /** Why this TPDO sends nothing now and what makes it send (issue 48); null: it sends. */
  idle?: PdoIdle | null;
}

/** One change that makes a silent event-driven TPDO send: a PDO change (needs control). */
export interface PdoIdleFix {
  label: string;
  /** The new transmission type, or null to keep it. */
  transmission_type: number | null;
  /** The new event timer [ms], or null to keep it. */
  event_timer: number | null;
}

export interface PdoIdle {
  why: string;
  fixes: PdoIdleFix[];
}

/** One mapped object's latest value from the cyclic data. */
export interface PdoLiveValue {
  /** The value as the frame carries it (integer counts); the backend sends `value` only. */
  raw?: number | string | boolean | null;
  value: number | string | boolean | null;
  engineering: number | null;
  /** Engineering unit. */
  unit: string | null;
  /** Name of the PDO that carried it. */
  pdo: string | null;
  /** Raw unit, when the server sends it (else the profile's). */
  raw_unit?: string | null;
  /** Backend addition: seconds since the frame that carried it. */
  age_s?: number | null;
  /** True while the link cannot vouch for it (EtherCAT: no valid working counter for some
   * cycles, or the link lost): the UI greys it (docs/ethercat.md "Link loss"). */
  stale?: boolean;
}

/** What the cycles say about an EtherCAT line (null on CAN). */
export interface PdoLinkHealth {
  state: 'ok' | 'degraded' | 'link lost' | 'recovering';
  reason: string | null;
  stale: boolean;
  cycles: number;
  wkc_errors: number;
  missing_frames: number;
  last_wkc: number | null;
  expected_wkc: number;
  carrier: boolean | null;
  losses: number;
  since_good_s: number | null;
  slaves: { position: number; node_id: number; wkc_errors: number; missing_frames: number; al_state: string | null; al_status_code: number }[];
}

export interface PdoCyclicStatus {
  running: boolean;
  sync_period_ms: number | null;
  /** How the drive synchronises to the exchange while it runs (null when stopped). */
  sync?: 'freerun' | 'dc' | null;
  outputs: boolean;
  rx_pdos: PdoRate[];
  tx_pdos: PdoRate[];
  frames_per_s: number;
  decode_errors: number;
  values: Record<string, PdoLiveValue>;
  /** EtherCAT: the line's health (link lost, working counter errors); null elsewhere. */
  link?: PdoLinkHealth | null;
  /** The received values are not the drive's present ones (see PdoLiveValue.stale). */
  stale?: boolean;
  /** Backend addition: SYNCs sent. */
  syncs?: number;
  /** Why the session's link carries no cyclic data (a CC-Link IE TSN station over SLMP
   * exchanges it with its manager only); null or absent when it does. */
  unavailable?: string | null;
  /** The synchronisations the session offers: "freerun", and "dc" on an EtherCAT drive whose
   * profile names its SYNC0 cycles. */
  sync_modes?: ('freerun' | 'dc')[];
  /** The SYNC0 cycles the drive takes: [min, max, step] in ns (null without DC). */
  dc_cycle_ns?: number[] | null;
}

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
