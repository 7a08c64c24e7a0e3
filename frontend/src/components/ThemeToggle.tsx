/**
 * The light/dark toggle at the foot of the navigation: Auto (the system's preference) ->
 * Light -> Dark. Not in the header: at 1024 px its room goes to the drive's state
 * (tests/browser/test_ui.py).
 */
import { chooseTheme, choiceLabel, nextChoice, themeState } from '../lib/theme';
import { useObservable } from '../state/observable';

export function ThemeToggle() {
  const { choice, theme } = useObservable(themeState);
  const label = choiceLabel(choice, theme);
  return (
    <button
      type="button"
      className="theme-toggle"
      data-testid="theme-toggle"
      data-choice={choice}
      data-theme={theme}
      title={`Colours: ${label}. Click for the next: Auto (the system's), Light, Dark.`}
      aria-label={`Colour theme: ${label}`}
      onClick={() => chooseTheme(nextChoice(choice))}
    >
      <span aria-hidden="true">{choice === 'system' ? '◐' : theme === 'dark' ? '☾' : '☀'}</span> {label}
    </button>
  );
}
