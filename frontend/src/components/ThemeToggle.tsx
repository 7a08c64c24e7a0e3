/** The header's light/dark toggle: Auto (the system's preference) -> Light -> Dark. */
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
      <span aria-hidden="true">{theme === 'dark' ? '☾' : '☀'}</span> {label}
    </button>
  );
}
