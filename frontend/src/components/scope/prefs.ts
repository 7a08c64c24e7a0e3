/**
 * What the scope page keeps in the browser, not on the server: trace colours and the math
 * channels (the server's channel list has neither), per browser in localStorage.
 */
import { MATH_OPS, type MathOp } from './math';

/**
 * The default colour of channel `id` is `CHANNEL_COLOURS[id]`: 8 hues in 4 tones, a tone for
 * each 8 ids (a drive's 8 when 4 drives fill the scope), so channels 0-7 keep the colours they
 * had when a scope had 8. Tones, not dash patterns: a decimated trace is drawn as one short
 * vertical stroke per pixel column (columns.ts) and a canvas restarts the dash pattern on every
 * stroke, so a dash would not show where 32 traces of 4 kHz data are drawn; the swatches of the
 * measurements and the colour pickers show a colour, not a pattern, too.
 *
 * Tones (HSL, from the first 8): 1 lighter by 0.10 and turned 20 degrees, 2 lighter by 0.22 and
 * turned -20 degrees, 3 lighter by 0.14, turned 10 degrees, at 35 % of the saturation (muted).
 * Chosen so that every two differ by a CIE76 delta E of at least 11 (the first 8 alone: 30) and
 * each has a contrast of at least 1.6:1 against both plot backgrounds (--plot-bg, light and
 * dark; the first 8: 2.1); prefs.test.ts checks both.
 */
export const CHANNEL_COLOURS = [
  ...['#1f5fa8', '#c25b12', '#1d7a3a', '#8e3ab5', '#c0262d', '#0f8a8a', '#8a6d00', '#4a5563'],
  ...['#273ed3', '#eab61d', '#27a377', '#ca58c8', '#d96c40', '#1481b8', '#a6bd00', '#606380'],
  ...['#57c5e0', '#ef6255', '#3bd038', '#a387d8', '#e3739d', '#22e7a5', '#fa7200', '#7e979f'],
  ...['#6a7ca4', '#af936d', '#57876e', '#a889ad', '#af847e', '#518590', '#8d8a44', '#747780'],
];
export const MATH_COLOURS = ['#d6338a', '#5c6bc0', '#2e9e9e', '#9a7b16'];

/** A math channel (docs/scope.md "Math channels"): computed in the browser. */
export interface MathDef {
  id: number;
  op: MathOp;
  a: number;
  b: number | null;
  visible: boolean;
  colour: string;
}

export const MAX_MATH = 4;

const KEY = 'servodesk.scope.prefs';

export interface ScopePrefs {
  colours: Record<string, string>;
  maths: MathDef[];
}

function storage(): Storage | null {
  try {
    return typeof localStorage === 'undefined' ? null : localStorage;
  } catch {
    return null;
  }
}

const COLOUR = /^#[0-9a-fA-F]{6}$/;

export function loadPrefs(): ScopePrefs {
  const empty: ScopePrefs = { colours: {}, maths: [] };
  const raw = storage()?.getItem(KEY);
  if (!raw) return empty;
  try {
    const p = JSON.parse(raw) as Partial<ScopePrefs>;
    const colours: Record<string, string> = {};
    for (const [k, v] of Object.entries(p.colours ?? {})) if (typeof v === 'string' && COLOUR.test(v)) colours[k] = v;
    const maths = (Array.isArray(p.maths) ? p.maths : [])
      .filter((m): m is MathDef => !!m && MATH_OPS.includes(m.op) && Number.isInteger(m.a) && Number.isInteger(m.id))
      .slice(0, MAX_MATH)
      .map((m) => ({ ...m, b: Number.isInteger(m.b) ? m.b : null, visible: m.visible !== false, colour: COLOUR.test(m.colour) ? m.colour : (MATH_COLOURS[m.id % MATH_COLOURS.length] as string) }));
    return { colours, maths };
  } catch {
    return empty;
  }
}

export function savePrefs(p: ScopePrefs): void {
  try {
    storage()?.setItem(KEY, JSON.stringify(p));
  } catch {
    // Storage full or disabled: the preferences last for this page only.
  }
}

export function channelColour(prefs: ScopePrefs, id: number): string {
  return prefs.colours[`c${id}`] ?? (CHANNEL_COLOURS[id % CHANNEL_COLOURS.length] as string);
}
