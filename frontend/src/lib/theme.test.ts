import { describe, expect, it } from 'vitest';
import { choiceLabel, nextChoice, parseChoice, resolveTheme } from './theme';

describe('theme', () => {
  it('follows the system unless the user chose', () => {
    expect(resolveTheme('system', true)).toBe('dark');
    expect(resolveTheme('system', false)).toBe('light');
    expect(resolveTheme('light', true)).toBe('light');
    expect(resolveTheme('dark', false)).toBe('dark');
  });

  it('reads only a known stored choice', () => {
    expect(parseChoice('dark')).toBe('dark');
    expect(parseChoice('light')).toBe('light');
    expect(parseChoice(null)).toBe('system');
    expect(parseChoice('purple')).toBe('system');
  });

  it('cycles system, light, dark and says what Auto gave', () => {
    expect(nextChoice('system')).toBe('light');
    expect(nextChoice('light')).toBe('dark');
    expect(nextChoice('dark')).toBe('system');
    expect(choiceLabel('system', 'dark')).toBe('Auto (dark)');
    expect(choiceLabel('dark', 'dark')).toBe('Dark');
  });
});
