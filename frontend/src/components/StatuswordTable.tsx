/**
 * The statusword (6041h) bit by bit with the drive's mode-specific names, as two halves side
 * by side (high byte 15..8, low byte 7..0) so the whole word fits beside the state diagram.
 */
import type { StatusBit } from '../api';
import { type StatuswordRow, statuswordRows } from '../lib/cia402';
import { toHex } from '../lib/format';

function Half({ rows }: { rows: StatuswordRow[] }) {
  return (
    <table className="grid sw-table">
      <thead>
        <tr>
          <th className="num">Bit</th>
          <th>Name</th>
          <th className="num">Value</th>
        </tr>
      </thead>
      <tbody>
        {rows.map((r) => (
          <tr key={r.bit} className={r.set ? 'bit-set' : 'bit-clear'} data-testid={`sw-bit-${r.bit}`} data-set={r.set ? '1' : '0'}>
            <td className="mono num">{r.bit}</td>
            <td className={r.fromDrive ? '' : 'muted-name'} title={r.name}>
              {r.name}
            </td>
            <td className="mono num">
              <span className={`lamp${r.set ? ' lamp-on' : ''}`} aria-hidden="true" />
              {r.set ? '1' : '0'}
            </td>
          </tr>
        ))}
      </tbody>
    </table>
  );
}

export function StatuswordTable({ statusword, bits }: { statusword: number; bits: StatusBit[] | null }) {
  const rows = statuswordRows(statusword, bits);
  const binary = statusword.toString(2).padStart(16, '0').replace(/(.{4})(?=.)/g, '$1 ');
  return (
    <div>
      <div className="sw-head mono">
        <span data-testid="statusword-hex">{toHex(statusword, 'UNSIGNED16')}</span>
        <span className="muted">{binary}</span>
      </div>
      <div className="sw-halves" data-testid="statusword-table">
        <Half rows={rows.slice(0, 8)} />
        <Half rows={rows.slice(8)} />
      </div>
    </div>
  );
}
