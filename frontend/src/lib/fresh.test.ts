import { describe, expect, it } from 'vitest';
import { Fresh } from './fresh';

function deferred<T>(): { promise: Promise<T>; resolve: (v: T) => void } {
  let resolve!: (v: T) => void;
  const promise = new Promise<T>((r) => (resolve = r));
  return { promise, resolve };
}

describe('Fresh', () => {
  it('applies a read whose answer comes before anything is pushed', async () => {
    const seen: string[] = [];
    const f = new Fresh<string>((v) => seen.push(v));
    expect(await f.read(async () => 'nobody')).toBe(true);
    expect(seen).toEqual(['nobody']);
  });

  it('drops a read overtaken by a pushed value (the stale GET after "Take control")', async () => {
    const seen: string[] = [];
    const f = new Fresh<string>((v) => seen.push(v));
    const answer = deferred<string>();
    const read = f.read(() => answer.promise);
    f.set('you');
    answer.resolve('nobody');
    expect(await read).toBe(false);
    expect(seen).toEqual(['you']);
  });

  it('applies a later read again', async () => {
    const seen: string[] = [];
    const f = new Fresh<string>((v) => seen.push(v));
    f.set('you');
    expect(await f.read(async () => 'other')).toBe(true);
    expect(seen).toEqual(['you', 'other']);
  });
});
