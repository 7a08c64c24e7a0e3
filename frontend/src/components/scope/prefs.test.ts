import { describe, expect, it } from 'vitest';
import { MAX_CHANNELS } from './ChannelTable';
import { CHANNEL_COLOURS, channelColour } from './prefs';

/** sRGB channel (0..1) to linear light (IEC 61966-2-1). */
function linear(c: number): number {
  return c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4;
}

function rgb(hex: string): [number, number, number] {
  return [1, 3, 5].map((i) => linear(parseInt(hex.slice(i, i + 2), 16) / 255)) as [number, number, number];
}

/** Relative luminance and contrast ratio (WCAG 2.1). */
function contrast(a: string, b: string): number {
  const y = (h: string) => {
    const [r, g, bl] = rgb(h);
    return 0.2126 * r + 0.7152 * g + 0.0722 * bl;
  };
  const [hi, lo] = [y(a), y(b)].sort((p, q) => q - p) as [number, number];
  return (hi + 0.05) / (lo + 0.05);
}

/** CIE L*a*b* (D65) and the CIE76 colour difference. */
function lab(hex: string): [number, number, number] {
  const [r, g, b] = rgb(hex);
  const f = (t: number) => (t > 0.008856 ? Math.cbrt(t) : 7.787 * t + 16 / 116);
  const x = f((0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047);
  const y = f(0.2126 * r + 0.7152 * g + 0.0722 * b);
  const z = f((0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883);
  return [116 * y - 16, 500 * (x - y), 200 * (y - z)];
}

function deltaE(a: string, b: string): number {
  const [p, q] = [lab(a), lab(b)];
  return Math.hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]);
}

/** The plot's backgrounds, light and dark (--plot-bg in styles.css). */
const BACKGROUNDS = ['#ffffff', '#1a2129'];

describe('channel colours', () => {
  const none = { colours: {}, maths: [] };
  const colours = Array.from({ length: MAX_CHANNELS }, (_, id) => channelColour(none, id));

  it('give each of the 32 channels a colour of its own', () => {
    expect(MAX_CHANNELS).toBe(32);
    expect(CHANNEL_COLOURS).toHaveLength(MAX_CHANNELS);
    expect(new Set(colours.map((c) => c.toLowerCase())).size).toBe(MAX_CHANNELS);
    for (const c of colours) expect(c).toMatch(/^#[0-9a-f]{6}$/); // What <input type=color> takes.
  });

  it('keep the first eight as they were with 8 channels', () => {
    expect(colours.slice(0, 8)).toEqual(['#1f5fa8', '#c25b12', '#1d7a3a', '#8e3ab5', '#c0262d', '#0f8a8a', '#8a6d00', '#4a5563']);
  });

  it('are told apart side by side and seen on both plot backgrounds', () => {
    let closest = Infinity;
    for (let i = 0; i < colours.length; i++)
      for (let j = i + 1; j < colours.length; j++) closest = Math.min(closest, deltaE(colours[i] as string, colours[j] as string));
    // A just-noticeable difference is about 2.3; traces need far more than that.
    expect(closest).toBeGreaterThanOrEqual(11);
    for (const c of colours) for (const bg of BACKGROUNDS) expect(contrast(c, bg), `${c} on ${bg}`).toBeGreaterThanOrEqual(1.6);
  });

  it('follow the colour the user chose for a channel', () => {
    expect(channelColour({ colours: { c31: '#123456' }, maths: [] }, 31)).toBe('#123456');
    expect(channelColour(none, 31)).toBe(CHANNEL_COLOURS[31]);
  });
});
