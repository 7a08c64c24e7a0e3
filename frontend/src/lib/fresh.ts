/**
 * Freshness of a value that arrives two ways: pushed (WebSocket messages, the answers to the
 * user's own actions) and read (a GET sent when a page opens). The read's answer may come
 * back after a newer push (a slow GET overtaken by the user's "Take control" and its
 * broadcast); applied then, it would put the older value back, and nothing would correct it
 * until the value changes again. A read applies only if nothing was set since it was sent.
 */
export class Fresh<T> {
  private version = 0;

  constructor(private readonly apply: (value: T) => void) {}

  /** A pushed value: always the newest. */
  set(value: T): void {
    this.version += 1;
    this.apply(value);
  }

  /** Reads a value and applies it unless another was set meanwhile; whether it was applied. */
  async read(get: () => Promise<T>): Promise<boolean> {
    const sent = this.version;
    const value = await get();
    if (this.version !== sent) return false;
    this.set(value);
    return true;
  }
}
