/**
 * Light or dark (issue 48): the system preference by default, or the user's choice from the
 * header's toggle, kept in this browser (localStorage). The choice sets <html data-theme>,
 * which selects the colour tokens of styles.css; it is applied before the first render so a
 * dark cabinet is not lit by a white flash on every load.
 */
import { Observable } from '../state/observable';

export type ThemeChoice = 'system' | 'light' | 'dark';
export type Theme = 'light' | 'dark';

export const THEME_KEY = 'servodesk.theme';

const ORDER: readonly ThemeChoice[] = ['system', 'light', 'dark'];

export function parseChoice(stored: string | null): ThemeChoice {
  return stored === 'light' || stored === 'dark' ? stored : 'system';
}

/** The theme a choice gives, with the system's preference for 'system'. */
export function resolveTheme(choice: ThemeChoice, systemDark: boolean): Theme {
  if (choice === 'system') return systemDark ? 'dark' : 'light';
  return choice;
}

/** The toggle's next choice: system -> light -> dark -> system. */
export function nextChoice(choice: ThemeChoice): ThemeChoice {
  return ORDER[(ORDER.indexOf(choice) + 1) % ORDER.length] ?? 'system';
}

export function choiceLabel(choice: ThemeChoice, theme: Theme): string {
  return choice === 'system' ? `Auto (${theme})` : choice === 'light' ? 'Light' : 'Dark';
}

export interface ThemeState {
  choice: ThemeChoice;
  theme: Theme;
}

export const themeState = new Observable<ThemeState>({ choice: 'system', theme: 'light' });

function systemQuery(): MediaQueryList | null {
  return typeof window !== 'undefined' && typeof window.matchMedia === 'function'
    ? window.matchMedia('(prefers-color-scheme: dark)')
    : null;
}

function readStored(): ThemeChoice {
  try {
    return parseChoice(window.localStorage.getItem(THEME_KEY));
  } catch {
    return 'system'; // storage refused (a locked-down browser): follow the system
  }
}

function apply(choice: ThemeChoice): void {
  const theme = resolveTheme(choice, systemQuery()?.matches ?? false);
  document.documentElement.dataset.theme = theme;
  themeState.set({ choice, theme });
}

/** Set the theme from the stored choice and follow the system's changes while on 'system'. */
export function startTheme(): void {
  apply(readStored());
  systemQuery()?.addEventListener('change', () => {
    if (themeState.get().choice === 'system') apply('system');
  });
}

export function chooseTheme(choice: ThemeChoice): void {
  try {
    if (choice === 'system') window.localStorage.removeItem(THEME_KEY);
    else window.localStorage.setItem(THEME_KEY, choice);
  } catch {
    // Not kept past this page; the choice still applies now.
  }
  apply(choice);
}

/** The colours a canvas chart (uPlot) draws its axes and grid in: canvas pixels do not follow
 * CSS, so a chart reads the tokens when it is made and is made again when the theme changes. */
export interface PlotColors {
  axis: string;
  grid: string;
  ticks: string;
  accent: string;
  text: string;
}

export function plotColors(): PlotColors {
  const css = getComputedStyle(document.documentElement);
  const v = (name: string, fallback: string): string => css.getPropertyValue(name).trim() || fallback;
  return {
    axis: v('--plot-axis', '#555555'),
    grid: v('--plot-grid', '#e4e7eb'),
    ticks: v('--border', '#ccccdd'),
    accent: v('--accent', '#1f5fa8'),
    text: v('--text', '#1c2430'),
  };
}
