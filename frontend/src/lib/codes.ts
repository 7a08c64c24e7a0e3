/**
 * Codes with their meaning, cause and remedy: SDO abort codes and PROFIdrive error numbers on
 * failed writes, and error/alarm codes held in objects (CiA 402 603Fh, the LECSN alarm and
 * tuning-error objects). The server sends the code and its meaning; the profile's error
 * tables (GET /profiles/{id} `error_list`) add the cause and remedy the manual gives.
 */
import { ApiError } from '../api/client';
import type { ErrorInfo, ObjectInfo, ObjectScalar } from '../api/types';
import { toHex } from './format';

/** Error tables to look in first for a protocol's code (profile `errors:` table names). */
const TABLES_BY_PROTOCOL: Record<string, readonly string[]> = {
  sdo: ['sdo_abort'],
  profile: ['sdo_abort'],
  coe: ['sdo_abort'],
  profidrive: ['profidrive'],
  slmp: ['slmp'],
};

export function findError(errors: readonly ErrorInfo[], code: number, protocol?: string | null, table?: string | null): ErrorInfo | null {
  const prefer = table ? [table] : (TABLES_BY_PROTOCOL[(protocol ?? '').toLowerCase()] ?? []);
  for (const t of prefer) {
    const hit = errors.find((e) => e.table === t && e.code === code);
    if (hit) return hit;
  }
  // A code carried by a protocol must come from that protocol's table when the profile has
  // one; otherwise any table with the code (an alarm number is unique enough to be useful).
  if (prefer.length && errors.some((e) => prefer.includes(e.table))) return null;
  return errors.find((e) => e.code === code) ?? null;
}

/** A failure as the pages show it: what failed, why, the code with meaning, cause and remedy. */
export interface Failure {
  action: string;
  message: string;
  hint: string | null;
  code: number | null;
  code_hex: string | null;
  meaning: string | null;
  protocol: string | null;
  /** The profile's entry for the code, when it has one (cause and remedy). */
  info: ErrorInfo | null;
}

export function failureOf(e: unknown, action: string, errors: readonly ErrorInfo[] = []): Failure {
  if (e instanceof ApiError) {
    const b = e.body;
    const code = b.code ?? (b.code_hex ? Number.parseInt(b.code_hex, 16) : null);
    return {
      action: e.action,
      message: b.message,
      hint: b.hint ?? null,
      code: code !== null && Number.isFinite(code) ? code : null,
      code_hex: b.code_hex ?? (b.code != null ? toHex(b.code, 'UNSIGNED32') : null),
      meaning: b.meaning ?? null,
      protocol: b.protocol ?? null,
      info: code !== null && Number.isFinite(code) ? findError(errors, code, b.protocol) : null,
    };
  }
  return {
    action,
    message: e instanceof Error ? e.message : String(e),
    hint: null,
    code: null,
    code_hex: null,
    meaning: null,
    protocol: null,
    info: null,
  };
}

/** A failure from an ErrorOut body inside a batch read answer. */
export function failureOfBody(
  body: { message: string; hint?: string | null; code?: number | null; code_hex?: string | null; meaning?: string | null; protocol?: string | null },
  action: string,
  errors: readonly ErrorInfo[] = [],
): Failure {
  const code = body.code ?? (body.code_hex ? Number.parseInt(body.code_hex, 16) : null);
  return {
    action,
    message: body.message,
    hint: body.hint ?? null,
    code: code !== null && Number.isFinite(code) ? code : null,
    code_hex: body.code_hex ?? (body.code != null ? toHex(body.code, 'UNSIGNED32') : null),
    meaning: body.meaning ?? null,
    protocol: body.protocol ?? null,
    info: code !== null && Number.isFinite(code) ? findError(errors, code, body.protocol) : null,
  };
}

/**
 * The profile's entry for a code an object holds: CiA 402 603Fh holds an error code
 * (CiA 402-2 §6.2, table error_code), and objects named "... error code" or "alarm ..." hold
 * codes of the family's own tables. Zero means "no error" and has no entry.
 */
export function codeInObject(o: Pick<ObjectInfo, 'index' | 'name'>, value: ObjectScalar | null | undefined, errors: readonly ErrorInfo[]): ErrorInfo | null {
  if (typeof value !== 'number' || !Number.isInteger(value) || value === 0 || errors.length === 0) return null;
  if (o.index === 0x603f) return findError(errors, value, null, 'error_code') ?? findError(errors, value, null);
  if (/error code|alarm|error number/i.test(o.name)) return findError(errors, value, null);
  return null;
}
