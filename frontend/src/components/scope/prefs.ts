/**
 * What the scope page keeps in the browser, not on the server: trace colours and the math
 * channels (the server's channel list has neither), per browser in localStorage.
 */
import { MATH_OPS, type MathOp } from './math';

export const CHANNEL_COLOURS = ['#1f5fa8', '#c25b12', '#1d7a3a', '#8e3ab5', '#c0262d', '#0f8a8a', '#8a6d00', '#4a5563'];
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
