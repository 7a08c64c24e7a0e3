/**
 * POST /motion/stop-all: the global stop (docs/api.md "StopAll", issue 48).
 *
 * Its own small fetch, like the other route modules (api/tuning.ts): the same headers as the
 * shared client (login token, the tab's client label; the control token is sent but the
 * server needs none for a stop). `keepalive` lets the request go out even when the person
 * closes or reloads the tab right after pressing stop.
 */
import { getToken } from './auth';
import { API_BASE, ApiError, normaliseErrorBody } from './client';
import { CLIENT_HEADER, tabClientId } from '../lib/backupClientId';
import { controlHeaders } from '../lib/controlToken';
import type { StopAllResult } from '../lib/globalStop';

export async function postStopAll(): Promise<StopAllResult> {
  const action = 'Stop all';
  const headers: Record<string, string> = {
    Accept: 'application/json',
    'Content-Type': 'application/json',
    [CLIENT_HEADER]: tabClientId(),
    ...controlHeaders(),
  };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  let res: Response;
  try {
    res = await fetch(`${API_BASE}/motion/stop-all`, { method: 'POST', headers, body: '{}', keepalive: true });
  } catch {
    throw new ApiError(action, 0, {
      error: 'NetworkError',
      message: 'the servodesk server did not answer: the stop may not have been sent',
      hint: 'stop the axes at the machine (QUICK STOP or the emergency stop); the dead-man stops the motion this tab started once its heartbeats are missing',
    });
  }
  const text = await res.text();
  let payload: unknown = text;
  try {
    payload = text ? JSON.parse(text) : null;
  } catch {
    // Keep the text: normaliseErrorBody shows it when it is short.
  }
  if (!res.ok) throw new ApiError(action, res.status, normaliseErrorBody(res.status, res.statusText, payload));
  return payload as StopAllResult;
}
