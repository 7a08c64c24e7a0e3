/**
 * POST /motion/stop-all: the global stop (docs/api.md "StopAll", issue 48), on the one fetch
 * wrapper (`./http`) with the same headers as every request (the control token is sent but
 * the server needs none for a stop). `keepalive` lets the request go out even when the person
 * closes or reloads the tab right after pressing stop; the error for no answer says the stop
 * may not have gone out and what to do instead.
 */
import { apiRequest } from './http';
import type { StopAllResult } from '../lib/globalStop';

/** Its message, motion and hint are always sent (null when there is none); the schema marks them optional. */
export function postStopAll(): Promise<StopAllResult> {
  return apiRequest('Stop all', 'POST', '/motion/stop-all', {
    keepalive: true,
    networkError: {
      error: 'NetworkError',
      message: 'the servodesk server did not answer: the stop may not have been sent',
      hint: 'stop the axes at the machine (QUICK STOP or the emergency stop); the dead-man stops the motion this tab started once its heartbeats are missing',
    },
  }) as Promise<StopAllResult>;
}
