import { describe, expect, it } from 'vitest';
import frames from '../../../tests/data/scope/frames.json';
import { KIND_CAPTURE, KIND_STATUS, ScopeWireError, decodeFrame } from './wire';

// Frames written by the Python encoder (tests/scope/test_scope_wire.py::fixture_frames), as hex.
function fixture(name: 'frame1' | 'status1'): Uint8Array {
  const hex = frames[name];
  const out = new Uint8Array(hex.length / 2);
  for (let i = 0; i < out.length; i++) out[i] = parseInt(hex.slice(2 * i, 2 * i + 2), 16);
  return out;
}

describe('decodeFrame', () => {
  it('decodes a capture frame written by the Python encoder', () => {
    const f = decodeFrame(fixture('frame1'));
    expect(f.kind).toBe(KIND_CAPTURE);
    expect([f.version, f.seq, f.skipped, f.flags, f.skippedBefore]).toEqual([1, 42, 3, 1, true]);
    expect(f.tRef).toBe(1_700_000_000.25);
    expect(f.blocks.map((b) => [b.id, b.sourceName, b.n, b.dt])).toEqual([
      [0, 'pdo', 4, 0.001],
      [5, 'sdo', 3, 0],
      [7, 'recorder', 0, 0.00025],
    ]);
    const [pdo, sdo, rec] = f.blocks;
    expect(Array.from(pdo!.values)).toEqual([1.5, -2.0, 3.25, 1e-9]);
    // Equidistant times are t0 + i * dt, the same doubles numpy computes.
    expect(Array.from(pdo!.times)).toEqual([0, 1, 2, 3].map((i) => -0.002 + i * 0.001));
    expect(sdo!.t0).toBe(0);
    expect(Array.from(sdo!.times)).toEqual([0.0, 0.0125, 0.03]);
    expect(Array.from(sdo!.values)).toEqual([100.0, 200.0, -0.001]);
    expect(rec!.values.length).toBe(0);
  });

  it('views the arrays without copying when they are aligned', () => {
    const bytes = fixture('frame1');
    const f = decodeFrame(bytes);
    expect(f.blocks[1]!.values.buffer).toBe(bytes.buffer);
    // At an odd offset inside a larger buffer the values are copied out and still right.
    const shifted = new Uint8Array(bytes.length + 1);
    shifted.set(bytes, 1);
    const g = decodeFrame(shifted.subarray(1));
    expect(Array.from(g.blocks[1]!.values)).toEqual([100.0, 200.0, -0.001]);
  });

  it('decodes a status frame', () => {
    const f = decodeFrame(fixture('status1').buffer as ArrayBuffer);
    expect(f.kind).toBe(KIND_STATUS);
    expect(f.seq).toBe(43);
    expect(f.status).toEqual({ type: 'status', running: true, state: 'armed' });
    expect(f.blocks).toEqual([]);
  });

  it('refuses a bad frame with a clear message', () => {
    const good = fixture('frame1');
    const patched = (at: number, byte: number) => {
      const copy = good.slice();
      copy[at] = byte;
      return copy;
    };
    expect(() => decodeFrame(good.subarray(0, 10))).toThrow(/truncated: 10 bytes, the header alone needs 32/);
    expect(() => decodeFrame(patched(0, 0x58))).toThrow(/not a scope frame: magic is "XDSC"/);
    expect(() => decodeFrame(patched(4, 2))).toThrow(/version 2 is not supported/);
    expect(() => decodeFrame(patched(5, 9))).toThrow(/kind 9 is unknown/);
    expect(() => decodeFrame(good.subarray(0, good.length - 8))).toThrow(/truncated in channel/);
    const longer = new Uint8Array(good.length + 3);
    longer.set(good);
    expect(() => decodeFrame(longer)).toThrow(/3 bytes after its 3 channel blocks/);
    expect(() => decodeFrame(patched(0, 0))).toThrow(ScopeWireError);
  });
});
