/**
 * REST shapes of the servodesk API v1, written by hand from docs/api.md.
 *
 * This file stands in for the generated `schema.ts` (npm run gen:api) until the backend's
 * openapi.json exists. Nothing imports it directly: every module imports from `./index`,
 * which is the one file to change when switching to the generated types.
 */

export interface ApiErrorBody {
  error: string;
  message: string;
  hint?: string | null;
  field?: string | null;
  code?: number | null;
  code_hex?: string | null;
  meaning?: string | null;
  protocol?: string | null;
  address?: string | null;
}

export interface Health {
  status: string;
  version: string;
  simulation: boolean;
  /** Link name -> null when usable, else the reason it is not. */
  links: Record<string, string | null>;
}

export interface ProfileSummary {
  id: string;
  name: string;
  vendor: string;
  fieldbus: string;
  description: string | null;
  objects: number;
  variables: number;
  errors: number;
  modes: number[];
  homing_methods: number[];
}

/** python-can interface names the backend accepts. */
export type BusInterface =
  | 'canalystii'
  | 'cantact'
  | 'etas'
  | 'gs_usb'
  | 'iscan'
  | 'ixxat'
  | 'kvaser'
  | 'neousys'
  | 'neovi'
  | 'nican'
  | 'nixnet'
  | 'pcan'
  | 'robotell'
  | 'seeedstudio'
  | 'serial'
  | 'slcan'
  | 'socketcan'
  | 'socketcand'
  | 'systec'
  | 'udp_multicast'
  | 'usb2can'
  | 'vector'
  | 'virtual';

/** Every interface a session opens on: python-can's (CANopen), slmp for a CC-Link IE TSN
 * station reached by SLMP over UDP (channel host:port, node id = axis + 1), profinet for a
 * PROFIdrive drive reached by PNIO-CM record access over UDP (channel host[:port], node id =
 * DO-ID), and ethercat for an EtherCAT line (channel the network interface, node id = slave
 * position + 1). */
export type SessionInterface = BusInterface | 'slmp' | 'profinet' | 'ethercat';

export interface ScanRequest {
  /** A python-can interface, or ethercat: the slaves of the line on the network interface
   * given as channel (node id = position + 1). */
  interface: BusInterface | 'ethercat';
  channel: string;
  bitrate: number | null;
  timeout: number;
}

export interface ScanNode {
  node_id: number;
  vendor_id: number;
  product_code: number;
  revision: number;
  serial: number;
  device_name: string | null;
  hardware_version?: string | null;
  software_version?: string | null;
  profile_id: string | null;
  /** The open session of this node, if any (backend addition, not in docs/api.md). */
  session_id?: string | null;
}

export interface ScanResult {
  nodes: ScanNode[];
}

/** POST /dcp/identify: the PROFINET devices on a network interface (docs/profinet.md, DCP). */
export interface DcpIdentifyRequest {
  nic: string;
  timeout?: number;
  name_of_station?: string | null;
}

export interface DcpDevice {
  mac: string;
  /** "" when the device has none (its Network Status LED: red single flash, 004 §20.2.3). */
  name_of_station: string | null;
  ip: string | null;
  netmask: string | null;
  gateway: string | null;
  ip_origin: 'not set' | 'static' | 'dhcp' | null;
  ip_conflict: boolean;
  vendor_id: number | null;
  device_id: number | null;
  type_of_station: string | null;
  roles: string[];
  instance: number | null;
  /** The open PROFINET session at this device's IP address, if any. */
  session_id: string | null;
  /** The channel to open a session with: its IP address (with the port where it is not
   * 34964, as for serve --sim's twin); null without an address. */
  channel: string | null;
  /** The profile whose vendor and device ID these are (its `dcp` quirk), if any. */
  profile_id?: string | null;
}

export interface DcpIdentifyResult {
  nic: string;
  devices: DcpDevice[];
  malformed: number;
}

export interface DcpSetRequest {
  nic: string;
  mac: string;
  name_of_station?: string | null;
  ip?: { ip: string; netmask: string; gateway: string } | null;
  permanent?: boolean;
}

export interface DcpDone {
  mac: string;
  done: string[];
}

export interface Identity {
  vendor_id: number | null;
  product_code: number | null;
  revision: number | null;
  serial: number | null;
  device_name: string | null;
  hardware_version: string | null;
  software_version: string | null;
}

export interface SessionRequest {
  interface: SessionInterface;
  channel: string;
  bitrate: number | null;
  node_id: number;
  profile: string | null;
}

export interface SessionInfo {
  id: string;
  node_id: number;
  interface: string;
  channel: string;
  bitrate: number | null;
  profile_id: string;
  profile_name: string;
  fieldbus: string;
  /** The link that carries the session (may differ from fieldbus for a simulated twin). */
  link?: string;
  simulated: boolean;
  note: string | null;
  identity: Identity;
  connected: boolean;
  state: string;
  nmt_state: string;
  /**
   * Addresses written through servodesk since the last store ("0x6081:00"): they differ from
   * the drive's non-volatile copy. Optional so an older server without it still type-checks.
   */
  dirty?: string[];
  /**
   * The encoder the session's engineering units are for. `rescaled`: the drive's 608Fh differs
   * from the profile's encoder, so the session's scales (GET /sessions/{sid}/profile) differ
   * from the family's (GET /profiles/{id}). Optional for an older server.
   */
  encoder?: SessionEncoder;
}

export interface SessionEncoder {
  counts_per_rev: number;
  source: '608Fh' | 'profile';
  rescaled: boolean;
}

export type ObjectScalar = number | string | boolean;

export interface ObjectValue {
  address: string;
  index: number;
  subindex: number;
  name: string | null;
  data_type: string | null;
  access: string | null;
  value: ObjectScalar | null;
  raw_hex: string;
  engineering: number | null;
  unit: string | null;
  raw_unit: string | null;
  value_text: string | null;
}

export type ObjectWrite = { value: ObjectScalar } | { raw_hex: string };

export interface ErrorInfo {
  table: string;
  code: number;
  code_hex: string;
  display: string | null;
  name: string;
  kind: string | null;
  cause: string | null;
  remedy: string | null;
  section: string | null;
}

export interface StatusBit {
  bit: number;
  name: string;
  set: boolean;
}

export interface DriveState {
  state: string;
  statusword: number;
  statusword_hex: string;
  bits: StatusBit[];
  mode: number | null;
  mode_name: string | null;
  position: number | null;
  velocity: number | null;
  position_unit: string | null;
  velocity_unit: string | null;
  position_eng: number | null;
  velocity_eng: number | null;
  /** Raw units of 6064h / 606Ch (backend addition, not in docs/api.md). */
  position_raw_unit?: string | null;
  velocity_raw_unit?: string | null;
  error_code: number | null;
  error: ErrorInfo | null;
  nmt_state: string | null;
  time: number;
}

export type StateCommand =
  | 'shutdown'
  | 'switch_on'
  | 'switch_on_enable'
  | 'enable_operation'
  | 'disable_operation'
  | 'disable_voltage'
  | 'quick_stop'
  | 'fault_reset'
  | 'enable'
  | 'disable';

export interface StateCommandRequest {
  command: StateCommand;
}

/** One object of a profile's dictionary (GET /profiles/{id} `object_list`). */
export interface ObjectInfo {
  index: number;
  subindex: number;
  address: string;
  name: string;
  name_local: string | null;
  data_type: string;
  /** "ro", "wo", "rw", "const" (CiA 301 access). */
  access: string;
  /** "none", "rx", "tx" (or "both"). */
  pdo_mapping: string;
  default: ObjectScalar | null;
  min: number | null;
  max: number | null;
  unit: string | null;
  scale: number;
  raw_unit: string | null;
  group: string | null;
  persist: boolean;
  process: boolean;
  description: string | null;
  section: string | null;
  values: Record<string, string> | null;
  pnu: number | null;
  symbol: string | null;
}

export interface GroupInfo {
  id: string;
  name: string;
  name_local: string | null;
  description: string | null;
}

export interface QuirkInfo {
  id: string;
  value: unknown;
  section: string | null;
  note: string | null;
}

/** An object of the profile's `network:` section: its address as `object_list` names it. */
export interface NetworkObjectInfo {
  address: string;
  note: string;
  section: string;
}

export interface NetworkRuleInfo {
  text: string;
  section: string;
}

export interface NetworkLedInfo {
  led: string;
  state: string;
  meaning: string;
  section: string;
}

/** How the family is addressed on its fieldbus (profile `network:`, docs/profiles.md). */
export interface NetworkInfo {
  summary: string;
  section: string;
  objects: NetworkObjectInfo[];
  addressing: NetworkRuleInfo[];
  leds: NetworkLedInfo[];
}

/** GET /profiles/{id}. */
export interface ProfileDetail extends ProfileSummary {
  groups: GroupInfo[];
  object_list: ObjectInfo[];
  error_list: ErrorInfo[];
  quirks: QuirkInfo[];
  /** null: the profile documents no network section. Optional for an older server. */
  network?: NetworkInfo | null;
}

/** One answer of POST /sessions/{sid}/read: the value, or why that one address failed. */
export type ReadItem = ObjectValue | { address: string; error: ApiErrorBody };

export interface ReadRequest {
  addresses: string[];
}

export interface ReadResponse {
  results: ReadItem[];
}

export interface StoreResult {
  /** Dirty entries now saved. */
  stored: number;
  duration_s: number;
  /** e.g. "0x1010:01 <- 0x65766173". */
  procedure: string;
}

export interface RestoreDefaultsRequest {
  confirm: boolean;
  reset: boolean;
}

export interface RestoreDefaultsResult {
  message: string;
}

export type DeviceDescriptionFormat = 'eds' | 'dcf' | 'esi';

// ---------------------------------------------------------------------------------------------
// Backups (issue 5) — docs/api.md "Backup, compare, restore (issue 5)". Appended by the
// Backup & restore page; everything above belongs to the other pages.
// ---------------------------------------------------------------------------------------------

/** Where a drive is on the bus when its backup was taken. */
export interface BackupBus {
  interface: string;
  channel: string;
  node_id: number;
}

/** An object the drive refused when a set was read: the set lacks it (issue 48). */
export interface UnreadableEntry {
  address: string;
  name: string;
  code: number | null;
  code_hex: string | null;
  message: string;
}

/** One stored backup (the file's metadata; the file itself never changes). */
export interface BackupInfo {
  id: string;
  /** When it was taken: ISO 8601 text (or seconds since the epoch from an older server). */
  time: string | number;
  label: string;
  note: string;
  profile_id: string;
  profile_version: string | number | null;
  /** Which physical drive it is (from its identity); GET /backups?drive= filters by it. */
  drive_key: string;
  identity: Identity;
  firmware: string | null;
  bus: BackupBus | null;
  entries: number;
  file: string;
  sha256: string;
  /** What the drive refused to give when it was read: the backup lacks these. */
  unreadable: UnreadableEntry[];
  /** False when `unreadable` is not empty. */
  complete: boolean;
}

export interface BackupRequest {
  label: string;
  note: string;
}

export interface BackupPatch {
  label?: string;
  note?: string;
}

export interface BackupFileEntry {
  address: string;
  name: string | null;
  data_type: string | null;
  raw_hex: string;
  value: ObjectScalar | null;
  unit: string | null;
}

/** GET /backups/{bid}: the JSON file's content. */
export interface BackupFile {
  schema_version: number;
  tool: string;
  time: string | number;
  label: string;
  note: string;
  profile: { id: string; version: string | number | null };
  identity: Identity;
  firmware: string | null;
  bus: BackupBus | null;
  entries: BackupFileEntry[];
}

export type BackupFormat = 'json' | 'dcf' | 'csv';

/** One side of a comparison. */
export type CompareSource =
  | { kind: 'drive'; session: string }
  | { kind: 'backup'; id: string }
  | { kind: 'defaults'; profile: string };

export interface CompareRequest {
  a: CompareSource;
  b: CompareSource;
  /** Also list the entries that are equal (the contract's "all"). */
  all: boolean;
}

/**
 * "changed" / "only_a" / "only_b" per the contract; with `all: true` the server may also list
 * equal entries, under a kind the contract does not name yet ("equal" or "same").
 */
export type DifferenceKind = 'changed' | 'only_a' | 'only_b' | 'equal' | 'same';

export interface Difference {
  address: string;
  name: string | null;
  group: string | null;
  unit: string | null;
  raw_unit: string | null;
  a_value: ObjectScalar | null;
  b_value: ObjectScalar | null;
  a_raw_hex: string | null;
  b_raw_hex: string | null;
  a_engineering: number | null;
  b_engineering: number | null;
  kind: DifferenceKind;
}

export interface Comparison {
  /** What A and B are, in words. */
  a: string;
  b: string;
  equal: boolean;
  differences: Difference[];
  /** Entries equal on both sides. */
  same: number;
  /** Objects a side lacks (unreadable when it was read): not compared. */
  a_unreadable: UnreadableEntry[];
  b_unreadable: UnreadableEntry[];
}

export interface PreflightRequest {
  backup: string;
  map_by_name: boolean;
}

export interface PreflightProblem {
  address: string | null;
  name: string | null;
  message: string;
  hint: string | null;
}

export interface NameMapping {
  address: string;
  name: string | null;
  /** The address on this drive with the same name, or null when it has none. */
  target: string | null;
  /** Why an entry has no target (backend addition, not in docs/api.md). */
  reason?: string | null;
}

export interface Preflight {
  ok: boolean;
  problems: PreflightProblem[];
  to_write: number;
  unchanged: number;
  read_only_skipped: number;
  /** For a backup of another family: how names map onto this drive's objects; else null. */
  mapping: NameMapping[] | null;
  /** Things to know that do not block the restore (backend addition, not in docs/api.md). */
  warnings?: string[];
  /** What the backup lacks (unreadable when it was taken): a restore cannot set these. */
  unreadable: UnreadableEntry[];
}

export interface RestoreRequest {
  backup: string;
  dry_run: boolean;
  store: boolean;
  force: boolean;
  map_by_name: boolean;
}

export type RestoreItemStatus = 'written' | 'unchanged' | 'skipped_read_only' | 'failed' | 'pending' | 'would_write';

export interface RestoreItem {
  address: string;
  name: string | null;
  status: RestoreItemStatus;
  old_raw_hex: string | null;
  new_raw_hex: string | null;
  code: number | null;
  code_hex: string | null;
  meaning: string | null;
  message: string | null;
}

export interface RestoreCounts {
  written: number;
  unchanged: number;
  skipped: number;
  failed: number;
  pending: number;
}

export interface RestoreReport {
  id: string;
  backup: string;
  session: string;
  time: string | number;
  dry_run: boolean;
  finished: boolean;
  stored: boolean;
  interrupted: boolean;
  /** The backup servodesk took automatically just before writing. */
  pre_backup: string | null;
  counts: RestoreCounts;
  items: RestoreItem[];
  /** Why it stopped or was not stored (backend addition, not in docs/api.md). */
  message?: string | null;
  /** The preflight's warnings (backend addition, not in docs/api.md). */
  warnings?: string[];
  /** What the backup lacks: this restore did not set these. */
  unreadable: UnreadableEntry[];
}

export interface AuditEntry {
  time: string | number;
  client: string;
  session: string | null;
  drive_key: string | null;
  address: string;
  name: string | null;
  old_raw_hex: string | null;
  new_raw_hex: string | null;
  old_value: ObjectScalar | null;
  new_value: ObjectScalar | null;
}

// ---------------------------------------------------------------------------------------------
// Operation and alarms (issue 4) — docs/api.md "Operation: control, motion, dead-man, homing,
// alarms". Appended by the Operation / Alarms / 3D view pages; shapes follow the backend
// (api/schemas.py), which adds a few fields to the contract (marked "backend addition").
// ---------------------------------------------------------------------------------------------

export type ControlAction = 'take' | 'release' | 'force_take';

export interface Control {
  session: string;
  /** The holder's client label (X-Servodesk-Client when it took control), or null. */
  owner: string | null;
  /** The account holding control ("local" in the single-user mode), or null. */
  user?: string | null;
  /** Unix time (s) when it was taken. */
  since: number | null;
  /** The request's X-Servodesk-Control token is the holder's. */
  you: boolean;
  /** The control token: only in the answer to the holder (take / force_take, GET with it). */
  token?: string | null;
  /** A WebSocket is bound to this control as the drive's dead-man. */
  bound?: boolean;
  /** The holder's bound socket closed: the drive was made safe, control lapses after 5 s
   * unless a reloaded page binds again with the token. */
  orphaned?: boolean;
  /** What stops this drive when its operator is lost (GET /control and the take answer). */
  protection?: ControlProtection | null;
}

export interface ControlProtection {
  /** Heartbeats older than this stop the axis. */
  deadman_ms: number;
  /** Where the dead-man's quick stop is sent from. */
  stop_path: 'dead-man thread' | 'event loop';
  /** The drive's own watchdog servodesk arms (a dead PC stops the axis), or null. */
  drive_watchdog: string | null;
  /** One sentence for people. */
  summary: string;
}

export interface JogRequest {
  /** Signed velocity, raw units. */
  velocity: number;
  /** Acceleration and deceleration, raw units (> 0). */
  acceleration: number;
}

export interface MoveRequest {
  mode: 'absolute' | 'relative';
  target: number;
  velocity?: number | null;
  acceleration?: number | null;
  deceleration?: number | null;
  immediate?: boolean;
}

export interface VelocityRequest {
  velocity: number;
  acceleration?: number | null;
  deceleration?: number | null;
}

export interface TorqueRequest {
  torque: number;
  slope?: number | null;
}

export type CyclicMode = 'csp' | 'csv' | 'cst';

export interface CyclicRequest {
  mode: CyclicMode;
  waveform: 'sine' | 'ramp';
  amplitude: number;
  frequency: number;
  duration: number;
}

export type MotionKind = 'jog' | 'move' | 'velocity' | 'torque' | 'cyclic' | 'homing' | 'tuning';

export interface MotionStatus {
  session: string;
  active: boolean;
  kind: MotionKind | null;
  owner: string | null;
  mode: number | null;
  target: number | null;
  /** idle, running, reached, done, halted, stopped, deadman or error. */
  state: string;
  message: string;
}

export interface UnitInfo {
  raw_unit: string | null;
  unit: string | null;
  scale: number;
  /** The profile's default of the object (raw), where it has one (limits only). */
  default?: number | null;
  /** What the ramp objects hold (limits' acceleration only; backend domain/ramps.py): a rate
   * in units per s², a time in ms to the rated speed (LECSN-T), or a register (CTMM04x). */
  ramp?: 'rate' | 'time' | 'register' | null;
}

export interface Limits {
  position_min: number | null;
  position_max: number | null;
  max_velocity: number | null;
  max_torque: number | null;
  max_acceleration: number | null;
  /** Backend addition: 60C6h. */
  max_deceleration: number | null;
  modes: number[];
  /** Backend addition: mode number -> name. */
  mode_names: Record<string, string>;
  /** position, velocity, torque, acceleration (each only when the profile has the object). */
  units: Partial<Record<'position' | 'velocity' | 'torque' | 'acceleration', UnitInfo>>;
  /** Backend addition: where each limit was read, e.g. "0x607F:00". */
  sources: Record<string, string>;
}

export type HomingSignal = 'home_switch' | 'limit_negative' | 'limit_positive' | 'index';

export interface HomingMethod {
  method: number;
  name: string;
  description: string;
  uses: HomingSignal[];
  direction: 'negative' | 'positive' | null;
  section: string | null;
  /** Backend addition: for a vendor method, the CiA 402 method it is simulated as. */
  equivalent?: number | null;
  /** Backend addition: the method needs Operation enabled to start. */
  needs_enable?: boolean;
}

export interface HomingRequest {
  method: number;
  speed_switch?: number | null;
  speed_zero?: number | null;
  acceleration?: number | null;
  offset?: number | null;
  /** The span the searches may cover (position units), for the estimate. */
  max_travel?: number | null;
  /** Halt and quick-stop the run after this many seconds (default: from the estimate). */
  timeout_s?: number | null;
}

/** One part of a homing run at one speed (domain/homing.py). */
export interface HomingPhase {
  name: string;
  distance: number;
  speed: number;
  seconds: number;
  speed_object: string;
}

export interface HomingEstimate {
  /** The longest a normal run takes from any start within the travel. */
  seconds: number;
  phases: HomingPhase[];
  assumptions: string[];
}

/** What a run is expected to take: GET /homing/plan, and part of every run. */
export interface HomingPlan {
  estimate_s: number | null;
  estimate: HomingEstimate | null;
  /** Where the travel came from, or why there is no estimate. */
  basis: string;
  travel: number | null;
  speed_switch: number | null;
  speed_zero: number | null;
  acceleration: number | null;
  timeout_s: number;
  timeout_source: 'user' | 'estimate' | 'default';
  warnings: string[];
}

/** How a run ended (running while it lasts): the motion's end, not only the statusword. */
export type HomingOutcome =
  | 'running'
  | 'attained'
  | 'error'
  | 'halted'
  | 'stopped'
  | 'deadman'
  | 'control_lost'
  | 'timeout'
  | 'interrupted';

export interface HomingRun extends HomingPlan {
  id: number;
  method: number;
  active: boolean;
  outcome: HomingOutcome;
  message: string;
  /** A motion under the client's dead-man. */
  watched: boolean;
  started_at: number;
  elapsed_s: number;
  /** What statusword bits 13/12/10 say (mode 6 only). */
  phase: string | null;
}

export interface HomingBits {
  target_reached: boolean;
  homing_attained: boolean;
  homing_error: boolean;
}

export type HomingState = 'idle' | 'running' | 'attained' | 'error';

export interface HomingStatus {
  session: string;
  method: number | null;
  state: HomingState;
  position: number | null;
  /** The backend sends the decoded bits (an object), not a list. */
  statusword_bits: HomingBits;
  message: string;
  /** The last run started through servodesk on this session. */
  run?: HomingRun | null;
}

export interface EmcyLogEntry {
  time: number | null;
  code: number;
  code_hex: string;
  name: string | null;
  cause: string | null;
  remedy: string | null;
  register: number;
}

export interface AlarmHistoryEntry {
  /** "1003h" or the family's object, e.g. "0x2A00:01". */
  source: string;
  index: number;
  code: number;
  code_hex: string;
  name: string;
  cause: string | null;
  remedy: string | null;
  /** Backend addition: operating hours of the entry, where the family records them. */
  time_h?: number | null;
}

export interface Alarms {
  session: string;
  current: ErrorInfo | null;
  state: string;
  emcy_log: EmcyLogEntry[];
  history: AlarmHistoryEntry[];
  reset_procedure: string;
  can_clear_history: boolean;
  /** POST /alarms/reset only: what the reset did (nothing is sent outside Fault). */
  message?: string | null;
}

/** GET /viewer: the viser 3D viewer. */
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

export interface PdoAssignment {
  rx: number[];
  tx: number[];
}

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

export interface PdoCyclicRequest {
  sync_period_ms: number;
  outputs: boolean;
  sync?: 'freerun' | 'dc';
}

export type PdoExportFormat = 'csv' | 'dcf' | 'esi' | 'json';

// --- Audit log (issue 45; docs/api.md "Audit log") ------------------------------------------

export type AuditCategory =
  | 'access_control'
  | 'request_error'
  | 'control'
  | 'motion'
  | 'write'
  | 'backup'
  | 'restore'
  | 'configuration'
  | 'user_admin';

/** One audit record (GET /audit), with its place in the hash chain. */
export interface AuditRecord {
  seq: number;
  /** ISO 8601 UTC, e.g. 2026-12-07T08:30:00.123456Z */
  time: string;
  user: string;
  /** The source address of the request (empty for the system: the dead-man, timers). */
  address: string;
  category: AuditCategory;
  /** Stable id, e.g. control.taken, motion.stopped, request.refused. */
  event: string;
  drive: string | null;
  result: 'success' | 'failure';
  message: string;
  details: Record<string, unknown>;
  prev: string;
  hash: string;
}

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
export interface AuditVerdict {
  ok: boolean;
  records: number;
  head: string;
  broken: number | null;
  problem: string | null;
}
