/**
 * The fleet (docs/api.md "Fleet and drift"): every drive the store knows across gateways,
 * plant tags, approved backups and drift results. Endpoint functions on the one fetch wrapper
 * (`./http`), typed from the schema.
 */
import { apiRequest } from './http';
import type { components } from './schema';

type S = components['schemas'];

export type FleetDrive = S['FleetDrive'];
export type FleetPage = S['FleetPage'];
export type DriftState = S['DriftStateOut']['state'];
export type DriftResult = S['DriftResult'];
export type Gateway = S['GatewayOut'];

export interface FleetFilter {
  q: string;
  drift: DriftState | null;
  offset: number;
  limit: number;
}

export const fleetApi = {
  list: (f: FleetFilter) =>
    apiRequest('List the fleet', 'GET', '/fleet', {
      query: { q: f.q, drift: f.drift, offset: f.offset, limit: f.limit },
    }),
  gateways: () => apiRequest('List the gateways', 'GET', '/fleet/gateways'),
  drift: (drive: string, limit = 20) => apiRequest(`Drift of ${drive}`, 'GET', '/fleet/drift', { query: { drive, limit } }),
  setTag: (drive: string, tag: string | null) => apiRequest(`Tag ${drive}`, 'PUT', '/fleet/tag', { body: { drive, tag } }),
  approve: (drive: string, backup: string, reason: string) =>
    apiRequest(`Approve ${backup}`, 'PUT', '/fleet/approved', { body: { drive, backup, reason } }),
  clearApproval: (drive: string, reason: string) =>
    apiRequest(`Clear the approval of ${drive}`, 'DELETE', '/fleet/approved', { body: { drive, reason } }),
  check: (sid: string) => apiRequest(`Check ${sid} for drift`, 'POST', '/sessions/{sid}/drift', { params: { sid } }),
};
