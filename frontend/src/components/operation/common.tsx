/** Small pieces shared by the motion panels: the limit line next to an input, a panel that
 * explains why a mode is not available, and the list of problems that keep Start disabled. */
import type { ReactNode } from 'react';
import type { Limits, UnitInfo } from '../../api/types';
import { FailureBox } from '../FailureBox';
import type { Failure } from '../../lib/codes';
import { formatQuantity } from '../../lib/motionLimits';
import { MODE_NAMES } from '../../lib/cia402';

/** "limit ±1000000 inc/s (457.8 rpm) · 0x607F:00", or "no limit" / "limit unknown". */
export function LimitNote({
  limits,
  name,
  unit,
  signed = true,
}: {
  limits: Limits | null;
  name: keyof Pick<Limits, 'max_velocity' | 'max_torque' | 'max_acceleration' | 'max_deceleration'>;
  unit: UnitInfo | undefined;
  signed?: boolean;
}) {
  if (!limits) return <>limit unknown (the server checks it)</>;
  const v = limits[name];
  const src = limits.sources[name];
  if (v === null) {
    // The server says "unknown: the drive refused ..." when it could not read the limit.
    if (src?.startsWith('unknown')) return <>limit unknown ({src.replace(/^unknown:\s*/, '')})</>;
    return <>no limit{src ? ` (${src})` : ''}</>;
  }
  return (
    <>
      limit {signed ? '±' : '≤ '}
      {formatQuantity(v, unit)}
      {src ? ` · ${src}` : ''}
    </>
  );
}

export function PositionLimitNote({ limits }: { limits: Limits | null }) {
  if (!limits) return <>software limits unknown (the server checks them)</>;
  const u = limits.units.position;
  if (limits.position_min === null && limits.position_max === null) {
    return <>no software position limits{limits.sources.position_min ? ` (${limits.sources.position_min})` : ''}</>;
  }
  return (
    <>
      software limits {formatQuantity(limits.position_min, u)} … {formatQuantity(limits.position_max, u)} · 607Dh
    </>
  );
}

export function ModeUnavailable({ mode, modes, what, testid }: { mode: number; modes: readonly number[]; what: string; testid: string }) {
  const have = modes.length ? modes.map((m) => MODE_NAMES[m] ?? `mode ${m}`).join(', ') : 'none listed';
  return (
    <div className="op-unavailable" data-testid={testid}>
      <strong>{what} is not available on this drive.</strong> It needs {MODE_NAMES[mode] ?? `mode ${mode}`} (6060h = {mode}),
      which is not among this family's documented modes of operation. The family has: {have}.
    </div>
  );
}

export function PanelFooter({
  problems,
  failure,
  children,
  testid,
}: {
  problems: readonly string[];
  failure: Failure | null;
  children: ReactNode;
  testid: string;
}) {
  return (
    <div className="op-footer">
      <div className="op-actions">{children}</div>
      {problems.length > 0 && (
        <ul className="op-problems" data-testid={`${testid}-problems`}>
          {problems.map((p) => (
            <li key={p}>{p}</li>
          ))}
        </ul>
      )}
      {failure && <FailureBox f={failure} testid={`${testid}-error`} />}
    </div>
  );
}

export function Hint({ children }: { children: ReactNode }) {
  return <div className="op-hint muted small">{children}</div>;
}
