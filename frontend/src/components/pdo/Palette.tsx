/**
 * The palette of mappable objects (GET /pdo/mappable), by direction and searchable: each
 * object is dragged into a PDO's entry list (HTML5 drag and drop). The keyboard alternative is
 * the Add select of each PDO.
 */
import { useMemo, useState } from 'react';
import type { MappableObject, PdoDirection } from '../../api/types';
import { type DragState, RESERVED_ENTRIES, startDrag } from './PdoCard';
import { dataTypeName, entryOfObject, filterMappable, paddingName } from './pdoModel';

export function Palette({
  mappable,
  padding,
  drag,
  readOnly,
}: {
  mappable: { rx: MappableObject[]; tx: MappableObject[] } | null;
  padding: boolean;
  drag: DragState;
  readOnly: boolean;
}) {
  const [direction, setDirection] = useState<PdoDirection>('tx');
  const [query, setQuery] = useState('');
  const list = useMemo(() => filterMappable(mappable?.[direction] ?? [], query), [mappable, direction, query]);
  const end = () => drag.end();

  return (
    <section className="card pdo-palette" data-testid="pdo-palette">
      <h2>Mappable objects</h2>
      <div className="segmented" role="tablist" aria-label="Direction">
        {(['rx', 'tx'] as const).map((d) => (
          <button
            key={d}
            type="button"
            role="tab"
            aria-selected={direction === d}
            className={direction === d ? 'on' : ''}
            onClick={() => setDirection(d)}
            data-testid={`pdo-palette-${d}`}
          >
            {d === 'rx' ? 'RX (to the drive)' : 'TX (from the drive)'} · {mappable?.[d].length ?? 0}
          </button>
        ))}
      </div>
      <input
        type="search"
        className="pdo-search"
        placeholder="Search: 6064, position, INTEGER32…"
        value={query}
        onChange={(e) => setQuery(e.target.value)}
        aria-label="Search the mappable objects"
        data-testid="pdo-palette-search"
      />
      {readOnly && <div className="muted small">This family's mapping cannot be changed.</div>}
      {!mappable && <div className="muted small">Loading…</div>}
      <ul className="pdo-palette-list" data-testid="pdo-palette-list">
        {padding &&
          RESERVED_ENTRIES.map((r) => (
            <li
              key={`reserved-${r.bits}`}
              className="padding"
              draggable={!readOnly}
              onDragStart={(e) => startDrag(e, { kind: 'object', direction: 'both', entry: r }, drag, paddingName(r))}
              onDragEnd={end}
              data-testid={`pdo-palette-reserved-${r.bits}`}
              title="Padding to fill the telegram to its size (004 §20.1.2)"
            >
              <span className="mono pdo-pal-addr">0000h</span>
              <span className="pdo-pal-name">{paddingName(r)}</span>
              <span className="muted small">padding</span>
            </li>
          ))}
        {list.map((o) => (
          <li
            key={o.address}
            draggable={!readOnly}
            onDragStart={(e) => startDrag(e, { kind: 'object', direction: o.direction, entry: entryOfObject(o) }, drag, o.address)}
            onDragEnd={end}
            data-testid={`pdo-palette-item-${o.address}`}
            data-address={o.address}
            title={`Drag into a ${direction === 'rx' ? 'RPDO' : 'TPDO'}`}
          >
            <span className="mono pdo-pal-addr">{o.address}</span>
            <span className="pdo-pal-name">{o.name}</span>
            <span className="muted small mono">
              {dataTypeName(o.data_type)} · {o.bits} bits{o.unit ? ` · ${o.unit}` : ''}
            </span>
          </li>
        ))}
        {mappable && list.length === 0 && <li className="muted small pdo-pal-empty">No object matches.</li>}
      </ul>
    </section>
  );
}
