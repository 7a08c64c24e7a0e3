/**
 * CiA 402 drive state machine facts the UI draws and decodes (CiA 402-2 §6.2): state names,
 * statusword patterns (table 30), the standard statusword bit names, the transitions of
 * figure 3 with their numbers, and the operation mode names (6060h values).
 *
 * The backend sends the decoded state and mode-specific bit names (DriveState); these tables
 * fill in when a name is missing and drive the diagram.
 */

export const STATES = [
  'Not ready to switch on',
  'Switch on disabled',
  'Ready to switch on',
  'Switched on',
  'Operation enabled',
  'Quick stop active',
  'Fault reaction active',
  'Fault',
] as const;

export type StateName = (typeof STATES)[number];

// CiA 402-2 table 30: (state, mask, value).
const PATTERNS: ReadonlyArray<readonly [StateName, number, number]> = [
  ['Not ready to switch on', 0x004f, 0x0000],
  ['Switch on disabled', 0x004f, 0x0040],
  ['Ready to switch on', 0x006f, 0x0021],
  ['Switched on', 0x006f, 0x0023],
  ['Operation enabled', 0x006f, 0x0027],
  ['Quick stop active', 0x006f, 0x0007],
  ['Fault reaction active', 0x004f, 0x000f],
  ['Fault', 0x004f, 0x0008],
];

export function decodeState(statusword: number): StateName | 'Unknown' {
  for (const [state, mask, value] of PATTERNS) if ((statusword & mask) === value) return state;
  return 'Unknown';
}

/** CiA 402-2 §6.2.3 table 31: generic statusword bit names (bits 12/13 depend on the mode). */
export const STANDARD_BITS: readonly string[] = [
  'Ready to switch on',
  'Switched on',
  'Operation enabled',
  'Fault',
  'Voltage enabled',
  'Quick stop',
  'Switch on disabled',
  'Warning',
  'Manufacturer specific',
  'Remote',
  'Target reached',
  'Internal limit active',
  'Operation mode specific',
  'Operation mode specific',
  'Manufacturer specific',
  'Manufacturer specific',
];

export interface StatuswordRow {
  bit: number;
  name: string;
  set: boolean;
  /** The name came from the drive's mode/profile (DriveState.bits), not the generic table. */
  fromDrive: boolean;
}

/**
 * Sixteen rows, bit 15 first (the order a statusword is read in hex). `set` is taken from the
 * statusword itself so the table can never disagree with the hex value shown beside it.
 */
export function statuswordRows(
  statusword: number,
  bits?: ReadonlyArray<{ bit: number; name: string }> | null,
): StatuswordRow[] {
  const names = new Map<number, string>();
  for (const b of bits ?? []) if (b.bit >= 0 && b.bit < 16 && b.name) names.set(b.bit, b.name);
  const rows: StatuswordRow[] = [];
  for (let bit = 15; bit >= 0; bit--) {
    const fromDrive = names.has(bit);
    rows.push({
      bit,
      name: names.get(bit) ?? STANDARD_BITS[bit] ?? `Bit ${bit}`,
      set: ((statusword >> bit) & 1) === 1,
      fromDrive,
    });
  }
  return rows;
}

/** 6060h / 6061h values (CiA 402-2 §6.3.1 table 34). */
export const MODE_NAMES: Readonly<Record<number, string>> = {
  0: 'No mode',
  1: 'Profile position (pp)',
  2: 'Velocity (vl)',
  3: 'Profile velocity (pv)',
  4: 'Profile torque (tq)',
  6: 'Homing (hm)',
  7: 'Interpolated position (ip)',
  8: 'Cyclic synchronous position (csp)',
  9: 'Cyclic synchronous velocity (csv)',
  10: 'Cyclic synchronous torque (cst)',
};

export function modeName(mode: number | null | undefined, fromDrive?: string | null): string {
  if (fromDrive) return fromDrive;
  if (mode === null || mode === undefined) return '—';
  return MODE_NAMES[mode] ?? (mode < 0 ? 'Manufacturer specific' : 'Reserved');
}

export interface DiagramTransition {
  n: number;
  from: StateName | 'Start';
  to: StateName;
  /** Command that triggers it, for the tooltip; internal transitions say so. */
  label: string;
}

/** CiA 402-2 figure 3 / table 29. */
export const TRANSITIONS: readonly DiagramTransition[] = [
  { n: 0, from: 'Start', to: 'Not ready to switch on', label: 'power on (internal)' },
  { n: 1, from: 'Not ready to switch on', to: 'Switch on disabled', label: 'self-test done (internal)' },
  { n: 2, from: 'Switch on disabled', to: 'Ready to switch on', label: 'Shutdown' },
  { n: 3, from: 'Ready to switch on', to: 'Switched on', label: 'Switch on' },
  { n: 4, from: 'Switched on', to: 'Operation enabled', label: 'Enable operation' },
  { n: 5, from: 'Operation enabled', to: 'Switched on', label: 'Disable operation' },
  { n: 6, from: 'Switched on', to: 'Ready to switch on', label: 'Shutdown' },
  { n: 7, from: 'Ready to switch on', to: 'Switch on disabled', label: 'Disable voltage / Quick stop' },
  { n: 8, from: 'Operation enabled', to: 'Ready to switch on', label: 'Shutdown' },
  { n: 9, from: 'Operation enabled', to: 'Switch on disabled', label: 'Disable voltage' },
  { n: 10, from: 'Switched on', to: 'Switch on disabled', label: 'Disable voltage / Quick stop' },
  { n: 11, from: 'Operation enabled', to: 'Quick stop active', label: 'Quick stop' },
  { n: 12, from: 'Quick stop active', to: 'Switch on disabled', label: 'Disable voltage / quick stop done' },
  { n: 13, from: 'Start', to: 'Fault reaction active', label: 'fault (internal, from any state)' },
  { n: 14, from: 'Fault reaction active', to: 'Fault', label: 'fault reaction done (internal)' },
  { n: 15, from: 'Fault', to: 'Switch on disabled', label: 'Fault reset' },
  { n: 16, from: 'Quick stop active', to: 'Operation enabled', label: 'Enable operation (605Ah = 5..8)' },
];
