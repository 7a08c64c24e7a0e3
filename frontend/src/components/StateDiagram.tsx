/**
 * The CiA 402 drive state machine (CiA 402-2 §6.2, figure 3) as SVG: the eight states as
 * boxes, the transitions as numbered arrows. The current state is lit, and the transitions a
 * command can take from it are drawn in the accent colour so a person sees what is possible.
 */
import { STATES, type StateName, TRANSITIONS } from '../lib/cia402';

const W = 160;
const H = 34;
const COL_A = 150;
const COL_B = 400;

const BOX: Readonly<Record<StateName, { x: number; y: number }>> = {
  'Not ready to switch on': { x: COL_A, y: 40 },
  'Switch on disabled': { x: COL_A, y: 110 },
  'Ready to switch on': { x: COL_A, y: 180 },
  'Switched on': { x: COL_A, y: 250 },
  'Operation enabled': { x: COL_A, y: 320 },
  'Fault reaction active': { x: COL_B, y: 40 },
  Fault: { x: COL_B, y: 110 },
  'Quick stop active': { x: COL_B, y: 320 },
};

const A_MID = COL_A + W / 2;
const B_MID = COL_B + W / 2;

/** Orthogonal paths (SVG path data) and label positions for each numbered transition. */
const PATHS: Readonly<Record<number, { d: string; lx: number; ly: number }>> = {
  0: { d: `M${A_MID},14 V40`, lx: A_MID + 12, ly: 27 },
  1: { d: `M${A_MID},74 V110`, lx: A_MID + 12, ly: 92 },
  2: { d: `M${A_MID - 18},144 V180`, lx: A_MID - 32, ly: 162 },
  7: { d: `M${A_MID + 18},180 V144`, lx: A_MID + 32, ly: 162 },
  3: { d: `M${A_MID - 18},214 V250`, lx: A_MID - 32, ly: 232 },
  6: { d: `M${A_MID + 18},250 V214`, lx: A_MID + 32, ly: 232 },
  4: { d: `M${A_MID - 18},284 V320`, lx: A_MID - 32, ly: 302 },
  5: { d: `M${A_MID + 18},320 V284`, lx: A_MID + 32, ly: 302 },
  // Left channel: the long "back" transitions.
  9: { d: `M${COL_A},346 H${COL_A - 110} V120 H${COL_A}`, lx: COL_A - 110, ly: 236 },
  8: { d: `M${COL_A},334 H${COL_A - 40} V197 H${COL_A}`, lx: COL_A - 40, ly: 300 },
  10: { d: `M${COL_A},264 H${COL_A - 75} V136 H${COL_A}`, lx: COL_A - 75, ly: 160 },
  // Right side: quick stop and fault.
  11: { d: `M${COL_A + W},331 H${COL_B}`, lx: (COL_A + W + COL_B) / 2, ly: 322 },
  16: { d: `M${COL_B},345 H${COL_A + W}`, lx: (COL_A + W + COL_B) / 2, ly: 356 },
  12: { d: `M${B_MID},320 V170 H${COL_A + W + 26} V138 H${COL_A + W}`, lx: B_MID + 12, ly: 240 },
  15: { d: `M${COL_B},122 H${COL_A + W}`, lx: (COL_A + W + COL_B) / 2, ly: 113 },
  13: { d: `M${B_MID},14 V40`, lx: B_MID + 12, ly: 27 },
  14: { d: `M${B_MID},74 V110`, lx: B_MID + 12, ly: 92 },
};

const INTERNAL = new Set([0, 1, 13, 14]);

export function slug(state: string): string {
  return state.toLowerCase().replace(/[^a-z0-9]+/g, '-');
}

export function StateDiagram({ state }: { state: string | null }) {
  const active = (STATES as readonly string[]).includes(state ?? '') ? (state as StateName) : null;
  return (
    <svg
      className="state-diagram"
      viewBox="0 0 580 372"
      role="img"
      aria-label={`CiA 402 state machine, current state ${state ?? 'unknown'}`}
      data-testid="state-diagram"
    >
      <defs>
        <marker id="sd-arrow" viewBox="0 0 8 8" refX="7" refY="4" markerWidth="7" markerHeight="7" orient="auto-start-reverse">
          <path d="M0,0 L8,4 L0,8 z" className="sd-arrowhead" />
        </marker>
        <marker id="sd-arrow-on" viewBox="0 0 8 8" refX="7" refY="4" markerWidth="7" markerHeight="7" orient="auto-start-reverse">
          <path d="M0,0 L8,4 L0,8 z" className="sd-arrowhead on" />
        </marker>
      </defs>
      <rect x={COL_B - 14} y={28} width={W + 28} height={130} rx={4} className="sd-zone sd-zone-fault" />
      <text x={COL_B + W + 10} y={150} className="sd-zone-label" textAnchor="end">
        fault
      </text>
      <rect x={COL_A - 14} y={304} width={COL_B + W - COL_A + 28} height={60} rx={4} className="sd-zone sd-zone-power" />
      <text x={COL_B + W + 10} y={360} className="sd-zone-label" textAnchor="end">
        power to motor
      </text>
      <circle cx={A_MID} cy={10} r={4} className="sd-start" />
      <text x={B_MID} y={10} className="sd-zone-label" textAnchor="middle">
        fault in any state
      </text>
      {TRANSITIONS.map((t) => {
        const p = PATHS[t.n];
        if (!p) return null;
        const on = active !== null && t.from === active && !INTERNAL.has(t.n);
        return (
          <g key={t.n} className={`sd-t${on ? ' on' : ''}${INTERNAL.has(t.n) ? ' internal' : ''}`}>
            <title>{`${t.n}: ${t.from} → ${t.to} (${t.label})`}</title>
            <path d={p.d} markerEnd={`url(#${on ? 'sd-arrow-on' : 'sd-arrow'})`} />
            <circle cx={p.lx} cy={p.ly} r={8} className="sd-num-bg" />
            <text x={p.lx} y={p.ly + 3.5} textAnchor="middle" className="sd-num">
              {t.n}
            </text>
          </g>
        );
      })}
      {STATES.map((s) => {
        const b = BOX[s];
        const on = s === active;
        return (
          <g key={s} className={`sd-state${on ? ' on' : ''}`} data-testid={`diagram-state-${slug(s)}`} data-active={on ? 'true' : 'false'}>
            <rect x={b.x} y={b.y} width={W} height={H} rx={3} />
            <text x={b.x + W / 2} y={b.y + H / 2 + 4} textAnchor="middle">
              {s}
            </text>
          </g>
        );
      })}
    </svg>
  );
}
