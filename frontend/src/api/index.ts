/**
 * The one place the UI takes its API types from.
 *
 * Today they come from the hand-written `./types`. Once `npm run gen:api` has produced
 * `./schema.ts` from backend/openapi.json, replace the export block at the bottom with the
 * aliases below (checked against the backend's schema; the UI type-checks with them):
 *
 *   import type { components } from './schema';
 *   type S = components['schemas'];
 *   export type ApiErrorBody = S['ErrorOut'];
 *   export type BusInterface = S['ScanRequest']['interface'];
 *   export type DriveState = S['DriveStateOut'];
 *   export type ErrorInfo = S['ErrorInfo'];
 *   export type Health = S['HealthOut'];
 *   export type Identity = S['IdentityOut'];
 *   export type ObjectScalar = number | string | boolean;
 *   export type ObjectValue = S['ObjectValueOut'];
 *   export type ObjectWrite = S['WriteRequest'];
 *   export type ProfileSummary = S['ProfileSummary'];
 *   export type ScanNode = S['ScanNode'];
 *   export type ScanRequest = S['ScanRequest'];
 *   export type ScanResult = S['ScanOut'];
 *   export type SessionInfo = S['SessionInfo'];
 *   export type SessionRequest = S['SessionCreate'];
 *   export type SessionInterface = S['SessionCreate']['interface'];
 *   export type StateCommand = S['StateCommand']['command'];
 *   export type StateCommandRequest = S['StateCommand'];
 *   export type StatusBit = S['StatusBit'];
 *
 * Nothing else in the UI changes.
 */
export type {
  ApiErrorBody,
  BusInterface,
  DcpDevice,
  DcpDone,
  DcpIdentifyRequest,
  DcpIdentifyResult,
  DcpSetRequest,
  DeviceDescriptionFormat,
  GroupInfo,
  NetworkInfo,
  NetworkLedInfo,
  NetworkObjectInfo,
  NetworkRuleInfo,
  ObjectInfo,
  ProfileDetail,
  QuirkInfo,
  ReadItem,
  ReadRequest,
  ReadResponse,
  RestoreDefaultsRequest,
  RestoreDefaultsResult,
  StoreResult,
  DriveState,
  ErrorInfo,
  Health,
  Identity,
  ObjectScalar,
  ObjectValue,
  ObjectWrite,
  ProfileSummary,
  ScanNode,
  ScanRequest,
  ScanResult,
  SessionInfo,
  SessionInterface,
  SessionRequest,
  StateCommand,
  StateCommandRequest,
  StatusBit,
} from './types';
