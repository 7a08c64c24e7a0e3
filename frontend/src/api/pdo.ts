/**
 * Typed endpoint functions of the PDO mapping and cyclic data routes (docs/pdo.md "REST",
 * `/api/v1/sessions/{sid}/pdo...`), on the one fetch wrapper (`./http`).
 *
 * A refused mapping answers 422 with the `problems` that name the PDO, entry and field, which
 * the page shows in place: the wrapper raises it as {@link PdoRefusedError}. The routes still
 * answer `dict[str, Any]` (issue 51 item 1), so the answers are the UI's own types
 * ({@link untyped}) until the backend gives them response models.
 */
import { apiDownload, apiRequest, untyped } from './http';
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
  view: (sid: string) =>
    untyped(apiRequest('Read the PDO configuration', 'GET', '/sessions/{sid}/pdo', { params: { sid } })) as Promise<PdoView>,
  mappable: (sid: string) =>
    untyped(apiRequest('Load the mappable objects', 'GET', '/sessions/{sid}/pdo/mappable', { params: { sid } })) as Promise<PdoMappable>,
  templates: (sid: string) =>
    untyped(apiRequest('Load the PDO templates', 'GET', '/sessions/{sid}/pdo/templates', { params: { sid } })) as Promise<PdoTemplate[]>,
  /** The template applied to the current configuration; nothing is written. */
  template: (sid: string, template_id: string, name: string) =>
    untyped(
      apiRequest(`Load template ${name}`, 'POST', '/sessions/{sid}/pdo/templates/{template_id}', {
        params: { sid, template_id },
      }),
    ) as Promise<PdoView>,
  validate: (sid: string, layout: PdoLayout) =>
    untyped(
      apiRequest('Check the mapping', 'POST', '/sessions/{sid}/pdo/validate', { params: { sid }, body: layout }),
    ) as Promise<PdoValidation>,
  plan: (sid: string, layout: PdoLayout) =>
    untyped(apiRequest('Plan the mapping', 'POST', '/sessions/{sid}/pdo/plan', { params: { sid }, body: layout })) as Promise<PdoPlan>,
  apply: (sid: string, body: PdoApplyRequest) =>
    untyped(
      apiRequest(body.dry_run ? 'Dry-run the mapping' : 'Apply the mapping', 'POST', '/sessions/{sid}/pdo/apply', {
        params: { sid },
        body,
      }),
    ) as Promise<PdoApplyReport>,
  export: (sid: string, format: PdoExportFormat) =>
    apiDownload(`Export the mapping as ${format.toUpperCase()}`, '/sessions/{sid}/pdo/export', {
      params: { sid },
      query: { format },
    }),
  cyclic: (sid: string) =>
    untyped(apiRequest('Read the cyclic data status', 'GET', '/sessions/{sid}/pdo/cyclic', { params: { sid } })) as Promise<PdoCyclicStatus>,
  startCyclic: (sid: string, body: PdoCyclicRequest) =>
    untyped(
      apiRequest('Start cyclic data', 'POST', '/sessions/{sid}/pdo/cyclic', { params: { sid }, body }),
    ) as Promise<PdoCyclicStatus>,
  stopCyclic: (sid: string) =>
    untyped(apiRequest('Stop cyclic data', 'DELETE', '/sessions/{sid}/pdo/cyclic', { params: { sid } })) as Promise<PdoCyclicStatus>,
  setOutputs: (sid: string, values: Record<string, number>) =>
    untyped(
      apiRequest('Set the cyclic outputs', 'PUT', '/sessions/{sid}/pdo/cyclic/outputs', { params: { sid }, body: { values } }),
    ) as Promise<PdoCyclicStatus>,
};
