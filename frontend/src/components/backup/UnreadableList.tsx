/**
 * What a backup (or a read of the drive) lacks because the drive refused to give it (issue
 * 48): how many, which, and each one's abort code and error text. Shown wherever a backup is
 * shown (taken, history, compare, restore preflight and report), so "1891 entries" never
 * reads as the whole drive when 541 objects could not be read.
 */
import type { UnreadableEntry } from '../../api/types';

/** "1 object" / "3 objects". */
export function objectsText(n: number): string {
  return `${n} object${n === 1 ? '' : 's'}`;
}

export function UnreadableList({ items, headline, testid, open = false }: { items: readonly UnreadableEntry[]; headline: string; testid: string; open?: boolean }) {
  if (items.length === 0) return null;
  return (
    <div className="bk-warn unreadable" data-testid={testid} data-count={items.length}>
      <strong data-testid={`${testid}-headline`}>{headline}</strong>
      <details open={open}>
        <summary className="small">
          {open ? 'The' : 'Show the'} {objectsText(items.length)} and why the drive refused {items.length === 1 ? 'it' : 'them'}
        </summary>
        <div className="bk-table-wrap">
          <table className="grid bk-table small" data-testid={`${testid}-table`}>
            <thead>
              <tr>
                <th>Address</th>
                <th>Name</th>
                <th>Abort code</th>
                <th>Error</th>
              </tr>
            </thead>
            <tbody>
              {items.map((u) => (
                <tr key={u.address} data-testid={`${testid}-row`} data-address={u.address}>
                  <td className="mono nowrap">{u.address}</td>
                  <td>{u.name || <span className="muted">—</span>}</td>
                  <td className="mono nowrap">{u.code_hex ?? '—'}</td>
                  <td>{u.message}</td>
                </tr>
              ))}
            </tbody>
          </table>
        </div>
      </details>
    </div>
  );
}
