/**
 * The one fetch wrapper of the UI: every REST request of /api/v1 goes through {@link send}
 * (docs/architecture.md "Wire contract").
 *
 * Paths, methods, path and query parameters, request bodies and answers are typed from
 * `./schema.ts`, which `npm run gen:api` generates from backend/openapi.json, itself generated
 * from the backend's pydantic models (`make openapi`). A path the backend does not serve, a
 * method it does not answer or a body of the wrong shape does not type-check.
 *
 * Every request carries the same headers: the tab's client label (`X-Servodesk-Client`, which
 * the server records in the audit log and which names the holder of control), the control
 * token while this tab holds control (`X-Servodesk-Control`, docs/api.md "Control and motion as
 * built"; reads ignore it), and the Authorization header when there is a token (the browser's
 * credential is the HttpOnly session cookie, so there is none). There is no CSRF token: the
 * server refuses a state change whose Origin is another site's and takes state changes only as
 * JSON or as a multipart file upload (docs/security.md), which is why a body is never sent as
 * text/plain.
 *
 * Every failure becomes an {@link ApiError} carrying the server's error body (message, protocol
 * code and its meaning, hint), so a page can say what failed, why and what to do instead of
 * showing JSON; a refused PDO mapping (422 with `problems`) becomes its subclass
 * {@link PdoRefusedError}, whose problems the page shows in place.
 */
import { authLost, getToken } from './auth';
import type { paths } from './schema';
import type { ApiErrorBody, PdoProblem } from './types';
import { CLIENT_HEADER, tabClientId } from '../lib/backupClientId';
import { controlHeaders } from '../lib/controlToken';

export const API_BASE = '/api/v1';

// ---------------------------------------------------------------------------------------------
// Types from the schema
// ---------------------------------------------------------------------------------------------

/** A path of the API below {@link API_BASE}, as the schema spells it (`/sessions/{sid}/state`). */
export type ApiPath = keyof paths extends infer K ? (K extends `${typeof API_BASE}${infer P}` ? P : never) : never;

export type Method = 'GET' | 'PUT' | 'POST' | 'DELETE' | 'PATCH';

/** The generated operation of a path and method (`undefined` where the path has no such method). */
type Op<P extends ApiPath, M extends Method> = paths[`${typeof API_BASE}${P}`][Lowercase<M>];

/** The methods a path answers. */
export type MethodOf<P extends ApiPath> = { [M in Method]: [Op<P, M>] extends [undefined] ? never : M }[Method];

type JsonOf<R> = R extends { content: { 'application/json': infer J } } ? J : undefined;

/** The JSON of the success answer (200, 201 or 202); `undefined` for 204 No Content. */
type OkOf<O> = O extends { responses: infer R }
  ? 200 extends keyof R
    ? JsonOf<R[200]>
    : 201 extends keyof R
      ? JsonOf<R[201]>
      : 202 extends keyof R
        ? JsonOf<R[202]>
        : undefined
  : never;

type ParamsOf<O> = O extends { parameters: { path: infer PP } } ? { params: PP } : { params?: undefined };

type QueryOf<O> = O extends { parameters: { query: infer Q } }
  ? { query: Q }
  : O extends { parameters: { query?: infer Q } }
    ? [Q] extends [undefined]
      ? { query?: undefined }
      : { query?: Q }
    : { query?: undefined };

/**
 * A JSON body, or a FormData where the route takes a file (multipart/form-data; a backup upload
 * also takes the file as a JSON body, the UI sends it as a form like every other file).
 */
type BodyOf<O> = O extends { requestBody: { content: { 'multipart/form-data': unknown } } }
  ? { body: FormData }
  : O extends { requestBody: { content: { 'application/json': infer B } } }
    ? { body: B }
    : O extends { requestBody?: { content: { 'application/json': infer B } } }
      ? [B] extends [undefined]
        ? { body?: undefined }
        : { body?: B }
      : { body?: undefined };

/** What changes how a request is sent or how its failure reads. */
export interface SendOptions {
  /** Let the request go out even when the tab closes or reloads right after (the stop). */
  keepalive?: boolean;
  /** The error body when the server does not answer at all (default: {@link NETWORK_ERROR}). */
  networkError?: ApiErrorBody;
  /**
   * Whether a 401 means the login is gone (default true). The login routes themselves say no:
   * a wrong password is a 401 too, and GET /auth/me answering 401 is how the UI learns it.
   */
  authLost?: boolean;
}

/** Path parameters, query and body as the schema types them for `path` and `method`. */
export type RequestInitOf<P extends ApiPath, M extends MethodOf<P>> = SendOptions &
  ParamsOf<Op<P, M>> &
  QueryOf<Op<P, M>> &
  BodyOf<Op<P, M>>;

/** The init argument: required where the route has path parameters, a required query or a body. */
type InitArg<P extends ApiPath, M extends MethodOf<P>> =
  Record<string, never> extends Omit<RequestInitOf<P, M>, keyof SendOptions>
    ? [init?: RequestInitOf<P, M>]
    : [init: RequestInitOf<P, M>];

/**
 * A request body that leaves out the fields `K` the server fills with their defaults.
 * openapi-typescript types a field with a default as present (true of every answer, which
 * always carries it); a request may leave it out, and the server's default then applies.
 */
export type ServerDefaults<B, K extends keyof B> = Omit<B, K> & Partial<Pick<B, K>>;

/** `body`, which leaves out the fields `K` the server fills with their defaults, as the schema's type. */
export function serverDefaults<B, K extends keyof B>(body: ServerDefaults<B, K>): B {
  return body as B;
}

/**
 * An answer with the fields `K` the server always sends, which the schema marks optional: a
 * pydantic field with a `default_factory` has no `default` in the JSON schema, so
 * openapi-typescript cannot tell that it is always there.
 */
export type Always<T, K extends keyof T> = Omit<T, K> & Required<Pick<T, K>>;

/** The answer of `method` on `path` as the schema types it. */
export type ResponseOf<P extends ApiPath, M extends MethodOf<P>> = OkOf<Op<P, M>>;

// ---------------------------------------------------------------------------------------------
// The error
// ---------------------------------------------------------------------------------------------

/** The project's one error of a request: what the user was doing, the status, the server's body. */
export class ApiError extends Error {
  readonly status: number;
  readonly body: ApiErrorBody;
  /** What the user was doing, e.g. "Write 0x6041:00". */
  readonly action: string;
  /** The answer as it came (parsed JSON, or text), for fields the error schema does not list. */
  readonly payload: unknown;

  constructor(action: string, status: number, body: ApiErrorBody, payload: unknown = null) {
    super(body.message);
    this.name = 'ApiError';
    this.action = action;
    this.status = status;
    this.body = body;
    this.payload = payload;
  }
}

/** A mapping the server refused before writing anything, with the problems it named. */
export class PdoRefusedError extends ApiError {
  readonly problems: PdoProblem[];

  constructor(action: string, status: number, body: ApiErrorBody, problems: PdoProblem[], payload: unknown = null) {
    super(action, status, body, payload);
    this.name = 'PdoRefusedError';
    this.problems = problems;
  }
}

export const NETWORK_ERROR: ApiErrorBody = {
  error: 'NetworkError',
  message: 'the servodesk server did not answer',
  hint: 'check that "servodesk serve" is still running and reachable from this browser',
};

/** Turn any error body the server may send into the documented shape. */
export function normaliseErrorBody(status: number, statusText: string, payload: unknown): ApiErrorBody {
  if (payload !== null && typeof payload === 'object') {
    const p = payload as Record<string, unknown>;
    if (typeof p.message === 'string') {
      return {
        error: typeof p.error === 'string' ? p.error : `HTTP ${status}`,
        message: p.message,
        hint: typeof p.hint === 'string' ? p.hint : null,
        field: typeof p.field === 'string' ? p.field : null,
        code: typeof p.code === 'number' ? p.code : null,
        code_hex: typeof p.code_hex === 'string' ? p.code_hex : null,
        meaning: typeof p.meaning === 'string' ? p.meaning : null,
        protocol: typeof p.protocol === 'string' ? p.protocol : null,
        address: typeof p.address === 'string' ? p.address : null,
      };
    }
    // FastAPI's default shape ({"detail": ...}); the contract says the server maps it, but a
    // person should still read a sentence if it slips through.
    const detail = p.detail;
    if (typeof detail === 'string') return { error: `HTTP ${status}`, message: detail };
    if (Array.isArray(detail)) {
      const parts = detail.map((d: unknown) => {
        if (d && typeof d === 'object') {
          const e = d as { loc?: unknown; msg?: unknown };
          const loc = Array.isArray(e.loc) ? e.loc.filter((x) => x !== 'body').join('.') : '';
          const msg = typeof e.msg === 'string' ? e.msg : 'invalid';
          return loc ? `${loc}: ${msg}` : msg;
        }
        return String(d);
      });
      return { error: `HTTP ${status}`, message: parts.join('; ') };
    }
  }
  const text = typeof payload === 'string' && payload.trim() && payload.length < 300 ? payload.trim() : '';
  return {
    error: `HTTP ${status}`,
    message: text || `the server answered ${status} ${statusText}`.trim(),
    hint: status === 401 ? 'log in again (your session ended)' : null,
  };
}

function str(v: unknown): string | null {
  return typeof v === 'string' ? v : null;
}

function int(v: unknown): number | null {
  return typeof v === 'number' && Number.isInteger(v) ? v : null;
}

/** The `problems` of an error answer (a refused PDO mapping), in the contract's shape; [] when none. */
export function problemsOf(payload: unknown): PdoProblem[] {
  if (!payload || typeof payload !== 'object') return [];
  const raw = (payload as { problems?: unknown }).problems;
  if (!Array.isArray(raw)) return [];
  const out: PdoProblem[] = [];
  for (const p of raw) {
    if (!p || typeof p !== 'object') continue;
    const o = p as Record<string, unknown>;
    const message = str(o.message);
    if (!message) continue;
    out.push({ message, pdo: str(o.pdo), entry: int(o.entry), field: str(o.field), section: str(o.section) });
  }
  return out;
}

/** The error of a failed answer's status and payload (parsed JSON, or the text). */
export function errorOf(action: string, status: number, statusText: string, payload: unknown): ApiError {
  const body = normaliseErrorBody(status, statusText, payload);
  const problems = problemsOf(payload);
  if (problems.length) {
    // The contract's 422 is {"detail", "problems"}: a sentence for the box above the tables.
    if (body.message.startsWith('the server answered')) body.message = problems.map((p) => p.message).join('; ');
    return new PdoRefusedError(action, status, body, problems, payload);
  }
  return new ApiError(action, status, body, payload);
}

// ---------------------------------------------------------------------------------------------
// Paths and queries
// ---------------------------------------------------------------------------------------------

type QueryValue = string | number | boolean | null | undefined;

/** Query text from the set parameters only (`undefined`/null/'' are left out). */
export function queryText(params: object | undefined): string {
  if (!params) return '';
  const parts = Object.entries(params as Record<string, QueryValue>)
    .filter(([, v]) => v !== undefined && v !== null && v !== '')
    .map(([k, v]) => `${encodeURIComponent(k)}=${encodeURIComponent(String(v))}`);
  return parts.length ? `?${parts.join('&')}` : '';
}

/** The path with its `{name}` parameters filled in, each one URL-encoded as one segment. */
export function fillPath(path: string, params: object | undefined): string {
  const values = (params ?? {}) as Record<string, string | number>;
  return path.replace(/\{([^}]+)\}/g, (_, name: string) => {
    const v = values[name];
    if (v === undefined) throw new Error(`no value for {${name}} of ${path}`);
    return encodeURIComponent(String(v));
  });
}

/** The URL of a GET, for a plain link (a device description download) where a fetch is not needed. */
export function apiUrl<P extends ApiPath>(path: P, ...[init]: InitArg<P, MethodOf<P> & 'GET'>): string {
  const i = (init as unknown as Raw | undefined) ?? {};
  return API_BASE + fillPath(path, i.params) + queryText(i.query);
}

// ---------------------------------------------------------------------------------------------
// Sending
// ---------------------------------------------------------------------------------------------

function headers(body: unknown): Record<string, string> {
  const h: Record<string, string> = { Accept: 'application/json', [CLIENT_HEADER]: tabClientId(), ...controlHeaders() };
  const token = getToken();
  if (token) h.Authorization = `Bearer ${token}`;
  // A FormData body (a file upload) gets its multipart/form-data type, with the boundary,
  // from the browser.
  if (body !== undefined && !(body instanceof FormData)) h['Content-Type'] = 'application/json';
  return h;
}

async function payloadOf(res: Response): Promise<unknown> {
  const text = await res.text();
  try {
    return text ? JSON.parse(text) : null;
  } catch {
    // Keep the text: normaliseErrorBody shows it when it is short.
    return text;
  }
}

interface Raw {
  params?: object;
  query?: object;
  body?: unknown;
}

/** The one fetch(): send, map "no answer" and every error status to an {@link ApiError}. */
async function send(action: string, method: Method, path: string, init: Raw & SendOptions): Promise<Response> {
  const { body } = init;
  let res: Response;
  try {
    res = await fetch(API_BASE + fillPath(path, init.params) + queryText(init.query), {
      method,
      headers: headers(body),
      body: body === undefined ? null : body instanceof FormData ? body : JSON.stringify(body),
      ...(init.keepalive ? { keepalive: true } : {}),
    });
  } catch {
    throw new ApiError(action, 0, init.networkError ?? NETWORK_ERROR);
  }
  // The login is gone (logged out elsewhere, idle time-out, ended by an administrator).
  if (res.status === 401 && init.authLost !== false) authLost('your session ended: log in again');
  if (!res.ok) throw errorOf(action, res.status, res.statusText, await payloadOf(res));
  return res;
}

/**
 * Send one request and return its JSON answer, typed from the schema.
 *
 * @param action what the user is doing, in words ("Write 0x6041:00"): the error says it
 * @param path the schema's path below /api/v1, with `{name}` placeholders that `params` fills
 */
export async function apiRequest<P extends ApiPath, M extends MethodOf<P>>(
  action: string,
  method: M,
  path: P,
  ...[init]: InitArg<P, M>
): Promise<ResponseOf<P, M>> {
  const res = await send(action, method, path, (init as unknown as (Raw & SendOptions) | undefined) ?? {});
  if (res.status === 204) return undefined as ResponseOf<P, M>;
  return (await payloadOf(res)) as ResponseOf<P, M>;
}

/** A downloaded file: its bytes and the name the server gave it. */
export interface DownloadedFile {
  blob: Blob;
  filename: string | null;
}

/** The file name of a Content-Disposition header (RFC 6266; filename* wins), or null. */
export function filenameFromDisposition(header: string | null): string | null {
  if (!header) return null;
  const star = /filename\*\s*=\s*(?:UTF-8|utf-8)?''([^;]+)/.exec(header);
  if (star?.[1]) {
    try {
      return decodeURIComponent(star[1].trim().replace(/^"|"$/g, ''));
    } catch {
      // Fall through to the plain form.
    }
  }
  const plain = /filename\s*=\s*("([^"]*)"|[^;]+)/.exec(header);
  const name = plain?.[2] ?? plain?.[1];
  return name ? name.trim() : null;
}

/**
 * GET a file with the same headers as every other request (client label, control token), so a
 * download works on a server that requires a login, where a plain link of another tab's
 * session would not; the bytes and the name from Content-Disposition.
 */
export async function apiDownload<P extends ApiPath>(
  action: string,
  path: P,
  ...[init]: InitArg<P, MethodOf<P> & 'GET'>
): Promise<DownloadedFile> {
  const res = await send(action, 'GET', path, (init as unknown as Raw | undefined) ?? {});
  return { blob: await res.blob(), filename: filenameFromDisposition(res.headers.get('Content-Disposition')) };
}

/**
 * A file upload's body: multipart/form-data with the file in field `file`. The server takes
 * state-changing requests only as JSON, or as multipart where a file is uploaded
 * (docs/security.md): a text/plain body is what a page of another site could post.
 */
export function fileForm(filename: string, content: BlobPart): FormData {
  const form = new FormData();
  form.append('file', new Blob([content]), filename);
  return form;
}
