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

export interface ScanRequest {
  interface: BusInterface;
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
  interface: BusInterface;
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
