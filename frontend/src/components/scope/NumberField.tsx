/** A number input that commits on Enter or leaving the field, and says when the text is no number. */
import { useEffect, useState } from 'react';

interface Props {
  value: number;
  onCommit: (v: number) => void;
  testid: string;
  min?: number;
  max?: number;
  step?: string;
  title?: string;
  className?: string;
  disabled?: boolean;
}

export function NumberField({ value, onCommit, testid, min, max, step = 'any', title, className, disabled }: Props) {
  const [text, setText] = useState(String(value));
  useEffect(() => setText(String(value)), [value]);
  const parsed = text.trim() === '' ? NaN : Number(text);
  const bad = !Number.isFinite(parsed) || (min !== undefined && parsed < min) || (max !== undefined && parsed > max);
  const commit = () => {
    if (!bad && parsed !== value) onCommit(parsed);
    else if (bad) setText(String(value));
  };
  return (
    <input
      type="number"
      className={`${className ?? ''}${bad ? ' scope-bad' : ''}`}
      value={text}
      step={step}
      min={min}
      max={max}
      title={bad ? `not a number${min !== undefined ? ` ≥ ${min}` : ''}${max !== undefined ? ` ≤ ${max}` : ''}` : title}
      disabled={disabled}
      onChange={(e) => setText(e.target.value)}
      onBlur={commit}
      onKeyDown={(e) => {
        if (e.key === 'Enter') commit();
      }}
      data-testid={testid}
    />
  );
}
