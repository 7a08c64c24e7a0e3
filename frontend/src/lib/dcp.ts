/**
 * PROFINET station names (DCP NameOfStation, IEC 61158-6-10), checked as the server checks
 * them (domain/dcp.py check_name_of_station) so that the Set button says what is wrong before
 * anything is sent; the server's answer names the rule as well.
 */

/** Why ``name`` is not a valid station name, or null ("" is "not changed"). */
export function nameProblem(name: string): string | null {
  if (name === '') return null;
  if (name !== name.toLowerCase()) return 'lower case only';
  if (name.length > 240) return 'at most 240 characters';
  for (const label of name.split('.')) {
    if (!/^[a-z0-9]([a-z0-9-]{0,61}[a-z0-9])?$/.test(label)) {
      return `"${label}": 1-63 of a-z, 0-9 and '-', no '-' at either end`;
    }
  }
  if (/^port-\d{3}(-\d{5})?$/.test(name.split('.')[0] ?? '')) return 'port-xyz names are reserved';
  if (/^\d+\.\d+\.\d+\.\d+$/.test(name)) return 'an IP address is not a name';
  return null;
}

/** The interface serve --sim's PROFINET twin answers DCP behind: its session's note says
 * "DCP: search network interface X." (SERVODESK_SIM_DCP=1). */
export function dcpNicFromNote(note: string | null | undefined): string | null {
  const m = /DCP: search network interface (\S+?)\./.exec(note ?? '');
  return m ? (m[1] ?? null) : null;
}

/** A PROFINET vendor or device ID as the GSDML writes it: 4 hex digits and "h" ("—": none). */
export function hex4(v: number | null | undefined): string {
  return v === null || v === undefined ? '—' : `${v.toString(16).toUpperCase().padStart(4, '0')}h`;
}
