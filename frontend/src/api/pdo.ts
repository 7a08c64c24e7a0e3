/**
 * Typed endpoint functions of the PDO mapping and cyclic data routes (docs/pdo.md "REST",
 * `/api/v1/sessions/{sid}/pdo...`), on the one fetch wrapper (`./http`).
 *
 * A refused mapping answers 422 with the `problems` that name the PDO, entry and field, which
 * the page shows in place: the wrapper raises it as {@link PdoRefusedError}. The answers are
 * the schema's types (api/schemas_pdo.py).
 */
import { apiDownload, apiRequest } from './http';
import type {
  PdoApplyReport,
  PdoApplyRequest,
  PdoCyclicRequest,
  PdoCyclicStatus,
  PdoExportFormat,
  PdoLayout,
  PdoMappable,
  PdoPlan,
  PdoTemplate,
  PdoValidation,
  PdoView,
} from './types';

export { PdoRefusedError, problemsOf } from './http';

export const pdoApi = {
  /** The drive's PDO configuration, read now. */
  view: (sid: string) => apiRequest('Read the PDO configuration', 'GET', '/sessions/{sid}/pdo', { params: { sid } }),
  mappable: (sid: string) =>
    apiRequest('Load the mappable objects', 'GET', '/sessions/{sid}/pdo/mappable', { params: { sid } }),
  templates: (sid: string) =>
    apiRequest('Load the PDO templates', 'GET', '/sessions/{sid}/pdo/templates', { params: { sid } }),
  /** The template applied to the current configuration; nothing is written. */
  template: (sid: string, template_id: string, name: string) =>
    apiRequest(`Load template ${name}`, 'POST', '/sessions/{sid}/pdo/templates/{template_id}', {
      params: { sid, template_id },
    }),
  validate: (sid: string, layout: PdoLayout) =>
    apiRequest('Check the mapping', 'POST', '/sessions/{sid}/pdo/validate', { params: { sid }, body: layout }),
  plan: (sid: string, layout: PdoLayout) =>
    apiRequest('Plan the mapping', 'POST', '/sessions/{sid}/pdo/plan', { params: { sid }, body: layout }),
  apply: (sid: string, body: PdoApplyRequest) =>
    apiRequest(body.dry_run ? 'Dry-run the mapping' : 'Apply the mapping', 'POST', '/sessions/{sid}/pdo/apply', {
      params: { sid },
      body,
    }),
  export: (sid: string, format: PdoExportFormat) =>
    apiDownload(`Export the mapping as ${format.toUpperCase()}`, '/sessions/{sid}/pdo/export', {
      params: { sid },
      query: { format },
    }),
  cyclic: (sid: string) =>
    apiRequest('Read the cyclic data status', 'GET', '/sessions/{sid}/pdo/cyclic', { params: { sid } }),
  startCyclic: (sid: string, body: PdoCyclicRequest) =>
    apiRequest('Start cyclic data', 'POST', '/sessions/{sid}/pdo/cyclic', { params: { sid }, body }),
  stopCyclic: (sid: string) => apiRequest('Stop cyclic data', 'DELETE', '/sessions/{sid}/pdo/cyclic', { params: { sid } }),
  setOutputs: (sid: string, values: Record<string, number>) =>
    apiRequest('Set the cyclic outputs', 'PUT', '/sessions/{sid}/pdo/cyclic/outputs', { params: { sid }, body: { values } }),
};
