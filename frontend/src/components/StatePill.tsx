/** The drive state as a coloured pill: green when enabled, red in fault, amber in quick stop. */

export function stateClass(state: string | null | undefined): string {
  switch (state) {
    case 'Operation enabled':
      return 'st-enabled';
    case 'Fault':
    case 'Fault reaction active':
      return 'st-fault';
    case 'Quick stop active':
      return 'st-qs';
    case 'Switched on':
    case 'Ready to switch on':
      return 'st-ready';
    default:
      return 'st-off';
  }
}

export function StatePill({ state, testid }: { state: string | null | undefined; testid?: string }) {
  return (
    <span className={`state-pill ${stateClass(state)}`} data-testid={testid}>
      {state ?? '—'}
    </span>
  );
}
