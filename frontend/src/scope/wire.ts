/**
 * Decoder of the scope's binary WebSocket frames (subprotocol `servodesk.scope.v1`).
 *
 * The layout (every offset, type and code) comes from layout.gen.ts, which
 * scripts/gen_scope_wire.py writes from backend/servodesk/domain/scope_wire.py, the one source
 * of the format (docs/scope.md "Wire format"); a status frame's JSON body is ScopeStatusFrame
 * in openapi.json. wire.test.ts decodes frames that the Python encoder wrote (tests/data/scope/).
 *
 * Every f64 array starts on an 8-byte boundary of the frame, so on a little-endian machine (all
 * browsers in practice) the arrays are Float64Array views on the received buffer, without a copy.
 */

import {
  BLOCK,
  BLOCK_SIZE,
  FLAG_SKIPPED,
  HEADER,
  HEADER_SIZE,
  KIND_CAPTURE,
  KIND_SAMPLES,
  KIND_STATUS,
  MAGIC,
  SOURCE_NAMES as SOURCES,
  VERSION,
  type WireType,
} from './layout.gen';

export {
  BLOCK_SIZE,
  FLAG_SKIPPED,
  HEADER_SIZE,
  KIND_CAPTURE,
  KIND_SAMPLES,
  KIND_STATUS,
  MAGIC,
  SUBPROTOCOL,
  VERSION,
} from './layout.gen';

export type FrameKind = typeof KIND_SAMPLES | typeof KIND_CAPTURE | typeof KIND_STATUS;
export type SampleSource = 'pdo' | 'sdo' | 'recorder';
export const SOURCE_NAMES: Readonly<Record<number, SampleSource>> = SOURCES;

export interface ScopeBlock {
  id: number;
  /** 1 pdo, 2 sdo, 3 recorder. */
  source: number;
  sourceName: SampleSource | 'unknown';
  n: number;
  /** Sample period (s) when the samples are equidistant, else 0. */
  dt: number;
  /** Offset of the first sample from the frame's tRef (s). */
  t0: number;
  /** Sample times as offsets from tRef (s); computed from t0 and dt when equidistant. */
  times: Float64Array;
  /** Raw values (scale and unit are in the channel list). */
  values: Float64Array;
}

export interface ScopeFrame {
  version: number;
  kind: FrameKind;
  flags: number;
  seq: number;
  skipped: number;
  /** Frames were dropped for this client just before this one (flag bit 0). */
  skippedBefore: boolean;
  /** Reference time, seconds on the backend's clock. */
  tRef: number;
  blocks: ScopeBlock[];
  /** The JSON body of a status frame (kind 3). */
  status: Record<string, unknown> | null;
}

/** A frame that does not follow the format; the message says what is wrong. */
export class ScopeWireError extends Error {
  constructor(message: string) {
    super(message);
    this.name = 'ScopeWireError';
  }
}

/** One fixed field of the layout (layout.gen.ts). */
interface WireField {
  readonly offset: number;
  readonly type: WireType;
}

/** A numeric field at ``base`` (the frame's or the block's start), little-endian. */
function field(view: DataView, base: number, f: WireField): number {
  const at = base + f.offset;
  switch (f.type) {
    case 'u8':
      return view.getUint8(at);
    case 'u16':
      return view.getUint16(at, true);
    case 'u32':
      return view.getUint32(at, true);
    case 'f64':
      return view.getFloat64(at, true);
    case 'bytes4':
      throw new ScopeWireError('a byte string is not a number');
  }
}

const LITTLE_ENDIAN = new Uint8Array(new Float64Array([1]).buffer)[7] === 0x3f;

function f64Array(bytes: Uint8Array, offset: number, n: number): Float64Array {
  const at = bytes.byteOffset + offset;
  if (LITTLE_ENDIAN && at % 8 === 0) return new Float64Array(bytes.buffer, at, n);
  const view = new DataView(bytes.buffer, at, n * 8);
  const out = new Float64Array(n);
  for (let i = 0; i < n; i++) out[i] = view.getFloat64(i * 8, true);
  return out;
}

/** Decode one frame; throws ScopeWireError when it is not exactly this format. */
export function decodeFrame(data: ArrayBuffer | Uint8Array): ScopeFrame {
  const bytes = data instanceof Uint8Array ? data : new Uint8Array(data);
  const size = bytes.byteLength;
  if (size < HEADER_SIZE) {
    throw new ScopeWireError(`scope frame truncated: ${size} bytes, the header alone needs ${HEADER_SIZE}`);
  }
  const view = new DataView(bytes.buffer, bytes.byteOffset, size);
  const m = HEADER.magic.offset;
  const magic = String.fromCharCode(bytes[m]!, bytes[m + 1]!, bytes[m + 2]!, bytes[m + 3]!);
  if (magic !== MAGIC) throw new ScopeWireError(`not a scope frame: magic is ${JSON.stringify(magic)}, expected "${MAGIC}"`);
  const version = field(view, 0, HEADER.version);
  if (version !== VERSION) {
    throw new ScopeWireError(
      `scope frame version ${version} is not supported (this page speaks ${VERSION}); reload the page after an upgrade`,
    );
  }
  const kind = field(view, 0, HEADER.kind);
  if (kind !== KIND_SAMPLES && kind !== KIND_CAPTURE && kind !== KIND_STATUS) {
    throw new ScopeWireError(`scope frame kind ${kind} is unknown (1 samples, 2 capture, 3 status)`);
  }
  const flags = field(view, 0, HEADER.flags);
  const frame: ScopeFrame = {
    version,
    kind,
    flags,
    seq: field(view, 0, HEADER.seq),
    skipped: field(view, 0, HEADER.skipped),
    skippedBefore: (flags & FLAG_SKIPPED) !== 0,
    tRef: field(view, 0, HEADER.t_ref),
    blocks: [],
    status: null,
  };
  if (kind === KIND_STATUS) {
    let body: unknown;
    try {
      body = JSON.parse(new TextDecoder('utf-8', { fatal: true }).decode(bytes.subarray(HEADER_SIZE)));
    } catch (e) {
      throw new ScopeWireError(`scope status frame: the body is not UTF-8 JSON (${String(e)})`);
    }
    if (body === null || typeof body !== 'object' || Array.isArray(body)) {
      throw new ScopeWireError('scope status frame: the JSON body is not an object');
    }
    frame.status = body as Record<string, unknown>;
    return frame;
  }
  const nchan = field(view, 0, HEADER.nchan);
  let off = HEADER_SIZE;
  for (let i = 0; i < nchan; i++) {
    if (size < off + BLOCK_SIZE) {
      throw new ScopeWireError(
        `scope frame truncated in channel block ${i + 1} of ${nchan}: ${size} bytes, its header ends at byte ${off + BLOCK_SIZE}`,
      );
    }
    const id = field(view, off, BLOCK.id);
    const source = field(view, off, BLOCK.source);
    const n = field(view, off, BLOCK.n);
    const dt = field(view, off, BLOCK.dt);
    const t0 = field(view, off, BLOCK.t0);
    off += BLOCK_SIZE;
    if (!(Number.isFinite(dt) && dt >= 0)) throw new ScopeWireError(`scope frame channel ${id}: sample period ${dt} is invalid`);
    const need = n * 8 * (dt > 0 ? 1 : 2);
    if (size < off + need) {
      throw new ScopeWireError(`scope frame truncated in channel ${id}: ${n} samples need ${need} bytes, ${size - off} are left`);
    }
    let times: Float64Array;
    if (dt > 0) {
      times = new Float64Array(n);
      for (let k = 0; k < n; k++) times[k] = t0 + k * dt;
    } else {
      times = f64Array(bytes, off, n);
      off += 8 * n;
    }
    const values = f64Array(bytes, off, n);
    off += 8 * n;
    frame.blocks.push({ id, source, sourceName: SOURCE_NAMES[source] ?? 'unknown', n, dt, t0, times, values });
  }
  if (off !== size) {
    throw new ScopeWireError(
      `scope frame has ${size - off} bytes after its ${nchan} channel blocks; the sender and this page disagree on the format`,
    );
  }
  return frame;
}
