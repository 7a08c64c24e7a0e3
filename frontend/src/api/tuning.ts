/**
 * REST client and shapes of the tuning routes (docs/tuning.md "Service and API", docs/api.md
 * "Tuning"): `/api/v1/sessions/{sid}/tuning...`.
 *
 * Requests go through the one fetch wrapper (`./http`), and failures become `ApiError`s
 * with the server's message and hint. The answers are the schema's types
 * (api/schemas_tuning.py); a key with `?` is one only some tunings send (the drive's own or
 * servodesk's).
 */
import { apiRequest } from './http';
import type { components } from './schema';

type S = components['schemas'];

export type TuningKind = S['TuningInfo']['kind'];
export type TuningMode = S['TuningDefaults']['mode'];
export type JobState = S['TuningJob']['state'];

/** A decoded result code: the drive's (builtin: P11604 with the profile's table) or servodesk's reason. */
export type TuningError = S['TuningError'];

export type TuningJob = S['TuningJob'];

/** The travel bound: start ± half the window [position units] (docs/tuning.md "Travel window"). */
export type TravelBound = S['TravelBound'];

export type GainRow = S['GainRow'];

export type TuningInfo = S['TuningInfo'];

export type StepMetrics = S['StepMetrics'];

export type StepResponse = S['StepResponse'];

export type Bode = S['Bode'];

export type ResultGain = S['ResultGain'];

export type Identified = S['Identified'];

/** `identified.refit`: the model's inertias fitted to the recordings of the winner's try. */
export type Refit = S['Refit'];

export type TuningResult = S['TuningResult'];

export type StartRequest = S['StartRequest'];

export type UndoResult = S['UndoResult'];

/** A tuning kept in the store (issue 49): metadata; StoredTuningResult adds its result. */
export type TuningRecord = S['TuningRecord'];
export type StoredTuningResult = S['StoredTuningResult'];

export const tuningApi = {
  info: (sid: string) => apiRequest('Read the tuning', 'GET', '/sessions/{sid}/tuning', { params: { sid } }),
  start: (sid: string, body: StartRequest) =>
    apiRequest('Start the tuning', 'POST', '/sessions/{sid}/tuning/start', { params: { sid }, body }),
  stop: (sid: string) => apiRequest('Stop the tuning', 'POST', '/sessions/{sid}/tuning/stop', { params: { sid }, body: {} }),
  result: (sid: string) => apiRequest('Read the tuning result', 'GET', '/sessions/{sid}/tuning/result', { params: { sid } }),
  undo: (sid: string, to: 'before' | 'defaults') =>
    apiRequest(to === 'before' ? 'Undo to the gains before tuning' : 'Undo to the default gains', 'POST', '/sessions/{sid}/tuning/undo', {
      params: { sid },
      body: { to },
    }),
  store: (sid: string) => apiRequest('Store to EEPROM', 'POST', '/sessions/{sid}/tuning/store', { params: { sid }, body: {} }),
  /** The drive's tunings kept in the store, newest first (from every session and gateway). */
  history: (sid: string, limit = 50) =>
    apiRequest('Read the tuning history', 'GET', '/sessions/{sid}/tuning/results', { params: { sid }, query: { limit } }),
  stored: (rid: string) => apiRequest('Open the stored tuning', 'GET', '/tuning/results/{rid}', { params: { rid } }),
};
