/**
 * Pick a readable, numeric object of a session's profile by typing part of its address, name
 * or symbol; the list marks objects a TPDO can carry (PDO) and the drive's recorder can record
 * (rec), the sources that sample faster than SDO polling.
 */
import { useMemo, useRef, useState } from 'react';
import type { ObjectInfo } from '../../api/types';

const NON_NUMERIC = new Set(['DOMAIN', 'VISIBLE_STRING', 'OCTET_STRING', 'UNICODE_STRING']);
const MAX_SHOWN = 40;

/** Objects the scope can sample: readable and numeric (the server checks it too). */
export function scopeObjects(list: readonly ObjectInfo[]): ObjectInfo[] {
  return list.filter((o) => o.access !== 'wo' && !NON_NUMERIC.has(o.data_type.toUpperCase()));
}

export function matchObjects(list: readonly ObjectInfo[], query: string, limit = MAX_SHOWN): ObjectInfo[] {
  const q = query.trim().toLowerCase();
  if (!q) return list.filter((o) => o.process).concat(list.filter((o) => !o.process)).slice(0, limit);
  const words = q.split(/\s+/);
  const hex = q.replace(/^0x/, '').replace(/h$/, '');
  const scored: { o: ObjectInfo; s: number }[] = [];
  for (const o of list) {
    const addr = o.address.toLowerCase();
    const hay = `${addr} ${o.name.toLowerCase()} ${(o.name_local ?? '').toLowerCase()} ${(o.symbol ?? '').toLowerCase()}`;
    if (!words.every((w) => hay.includes(w))) continue;
    const s = addr.replace(/^0x/, '').startsWith(hex) ? 0 : o.name.toLowerCase().startsWith(q) ? 1 : o.process ? 2 : 3;
    scored.push({ o, s });
  }
  scored.sort((x, y) => x.s - y.s || x.o.index - y.o.index || x.o.subindex - y.o.subindex);
  return scored.slice(0, limit).map((x) => x.o);
}

interface Props {
  objects: readonly ObjectInfo[] | null;
  address: string;
  recordable: ReadonlySet<string>;
  onPick: (address: string) => void;
  testid: string;
}

export function ObjectPicker({ objects, address, recordable, onPick, testid }: Props) {
  const [query, setQuery] = useState<string | null>(null);
  const [open, setOpen] = useState(false);
  const box = useRef<HTMLDivElement | null>(null);
  const list = useMemo(() => (objects ? scopeObjects(objects) : []), [objects]);
  const current = list.find((o) => o.address.toUpperCase() === address.toUpperCase());
  const shown = useMemo(() => (open ? matchObjects(list, query ?? '') : []), [open, list, query]);

  const pick = (o: ObjectInfo) => {
    onPick(o.address);
    setQuery(null);
    setOpen(false);
  };

  return (
    <div
      className="scope-picker"
      ref={box}
      onBlur={(e) => {
        if (!box.current?.contains(e.relatedTarget as Node | null)) {
          setOpen(false);
          setQuery(null);
        }
      }}
    >
      <input
        type="search"
        value={query ?? (current ? `${current.address} ${current.name}` : address)}
        placeholder={objects ? 'search address or name…' : 'loading the profile…'}
        disabled={!objects}
        onFocus={(e) => {
          setOpen(true);
          setQuery('');
          e.currentTarget.select();
        }}
        onChange={(e) => {
          setQuery(e.target.value);
          setOpen(true);
        }}
        onKeyDown={(e) => {
          if (e.key === 'Enter' && shown[0]) {
            e.preventDefault();
            pick(shown[0]);
          } else if (e.key === 'Escape') {
            setOpen(false);
            setQuery(null);
          }
        }}
        data-testid={testid}
        title={current ? `${current.address} ${current.name}${current.unit ? ` [${current.unit}]` : ''}` : undefined}
      />
      {open && (
        <ul className="scope-picker-list" role="listbox" data-testid={`${testid}-list`}>
          {shown.length === 0 && <li className="muted small">no readable numeric object matches</li>}
          {shown.map((o) => (
            <li key={o.address}>
              <button type="button" tabIndex={0} onMouseDown={(e) => e.preventDefault()} onClick={() => pick(o)} data-testid={`scope-object-${o.address}`}>
                <span className="mono">{o.address}</span> {o.name}
                {o.unit && <span className="muted"> [{o.unit}]</span>}
                {(o.pdo_mapping === 'tx' || o.pdo_mapping === 'both') && <span className="scope-tag">PDO</span>}
                {recordable.has(o.address.toUpperCase()) && <span className="scope-tag">rec</span>}
              </button>
            </li>
          ))}
        </ul>
      )}
    </div>
  );
}
