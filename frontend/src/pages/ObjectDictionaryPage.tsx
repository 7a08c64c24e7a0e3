/**
 * Object dictionary: every object of the session's profile (lecsn-t has 2912), with address,
 * name (local name on hover), type, access, PDO mapping, default, limits, unit and the live
 * value once read. The search box takes an index the way manuals write it (6040, 0x6040,
 * 6040h, P24640) or words of the name, local name, symbol and description; filters narrow by
 * group, access, PDO mappability and "differs from default".
 *
 * Typing stays fast: each object's search text is built once per profile (lib/dictionary.ts)
 * and only the rows in view are drawn (components/VirtualTable.tsx). Live values are read
 * only on request ("Read values"), for the filtered rows, 256 per POST /read, with progress.
 * A row opens a detail panel with the description, manual section, enumeration and a write
 * checked like on the Parameters page.
 */
import { type KeyboardEvent, useCallback, useEffect, useMemo, useRef, useState } from 'react';
import { api } from '../api/client';
import type { ObjectInfo, ObjectValue, ObjectWrite, ProfileDetail } from '../api/types';
import { CodeInfo, FailureBox } from '../components/FailureBox';
import { useWriteGate } from '../components/ControlNote';
import { ProgressBar } from '../components/ProgressBar';
import { ValueEditor } from '../components/ValueEditor';
import { VirtualTable } from '../components/VirtualTable';
import { type Failure, codeInObject, failureOf, failureOfBody } from '../lib/codes';
import {
  type DictionaryFilter,
  NO_FILTER,
  batches,
  buildSearchIndex,
  canonicalAddress,
  differsFromDefault,
  filterObjects,
  formatPnu,
  isPdoMappable,
  isReadable,
  isWritable,
} from '../lib/dictionary';
import type { NumberMode } from '../lib/format';
import { rangeText } from '../lib/validate';
import { decText, engineeringText, enumText, hexText, isObjectValue } from '../lib/values';
import { useSessionInfo, useSessionProfile } from '../state/profileCache';
import './dataPages.css';
import type { PageProps } from './registry';

const ROW_HEIGHT = 25;
const READ_BATCH = 256;

type Cell = { v: ObjectValue } | { f: Failure };

function pdoText(p: string): string {
  if (!p || p === 'none' || p === 'no') return '';
  return p === 'rx' ? 'RxPDO' : p === 'tx' ? 'TxPDO' : p === 'both' ? 'Rx/Tx' : p;
}

/** UNSIGNED32 -> U32, INTEGER16 -> I16, REAL32 -> R32: the table column is narrow. */
function shortType(t: string): string {
  return t.replace('UNSIGNED', 'U').replace('INTEGER', 'I').replace('REAL', 'R').replace('VISIBLE_STRING', 'STR').replace('OCTET_STRING', 'OCT');
}

let renderedMarked = false;

export function ObjectDictionaryPage({ sid }: PageProps) {
  const { info } = useSessionInfo(sid);
  const { profile, error: profileError } = useSessionProfile(info);
  if (profileError) return <FailureBox f={failureOf(profileError, 'Load the profile')} />;
  if (!info || !profile) return <div className="muted">Loading the profile…</div>;
  return <Dictionary sid={sid} profile={profile} dirtyList={info.dirty ?? []} />;
}

function Dictionary({ sid, profile, dirtyList }: { sid: string; profile: ProfileDetail; dirtyList: readonly string[] }) {
  const objects = profile.object_list;
  const errors = profile.error_list;
  // Writes need control of the drive: without it the editor's Write says why.
  const blocked = useWriteGate(sid, { write: 'write_parameters' }).write;
  const index = useMemo(() => buildSearchIndex(objects), [objects]);
  const groupNames = useMemo(() => new Map(profile.groups.map((g) => [g.id, g.name])), [profile]);
  const usedGroups = useMemo(() => {
    const used = new Set(objects.map((o) => o.group ?? ''));
    return profile.groups.filter((g) => used.has(g.id));
  }, [objects, profile]);
  const showPnu = useMemo(() => objects.some((o) => o.pnu !== null), [objects]);
  const dirty = useMemo(() => new Set(dirtyList.map(canonicalAddress)), [dirtyList]);

  const [filter, setFilter] = useState<DictionaryFilter>(NO_FILTER);
  const [cells, setCells] = useState<Map<string, Cell>>(() => new Map());
  const [selected, setSelected] = useState<number | null>(null);
  const [reading, setReading] = useState<{ done: number; total: number } | null>(null);
  const [readFailure, setReadFailure] = useState<Failure | null>(null);
  const [mode, setMode] = useState<NumberMode>('dec');
  const cancelRead = useRef(0);

  const live = useCallback(
    (o: ObjectInfo) => {
      const c = cells.get(o.address);
      return c && 'v' in c ? c.v.value : undefined;
    },
    [cells],
  );
  const rows = useMemo(() => filterObjects(objects, index, filter, live), [objects, index, filter, live]);
  const known = useMemo(() => rows.reduce((n, i) => n + (cells.has((objects[i] as ObjectInfo).address) ? 1 : 0), 0), [rows, cells, objects]);

  useEffect(() => {
    if (!renderedMarked && typeof performance !== 'undefined') {
      // For bench/bench_ui_search.py: the first time the dictionary table is drawn.
      renderedMarked = true;
      performance.mark('servodesk:od-rendered');
    }
  }, []);

  const set = (patch: Partial<DictionaryFilter>) => setFilter((f) => ({ ...f, ...patch }));

  async function readValues() {
    const token = ++cancelRead.current;
    const addrs = rows.map((i) => objects[i] as ObjectInfo).filter(isReadable).map((o) => o.address);
    setReadFailure(null);
    setReading({ done: 0, total: addrs.length });
    let done = 0;
    for (const batch of batches(addrs, READ_BATCH)) {
      try {
        const res = await api.readMany(sid, batch);
        if (token !== cancelRead.current) return;
        setCells((prev) => {
          const next = new Map(prev);
          res.results.forEach((r, i) => {
            const addr = canonicalAddress(r.address ?? batch[i] ?? '');
            if (isObjectValue(r)) next.set(addr, { v: r });
            else if ('error' in r) next.set(addr, { f: failureOfBody(r.error, `Read ${addr}`, errors) });
          });
          return next;
        });
      } catch (e) {
        if (token !== cancelRead.current) return;
        setReadFailure(failureOf(e, `Read ${batch.length} objects`, errors));
        setReading(null);
        return;
      }
      done += batch.length;
      setReading({ done, total: addrs.length });
    }
    if (token === cancelRead.current) setReading(null);
  }

  async function readOne(o: ObjectInfo) {
    try {
      const v = await api.readObject(sid, o.address);
      setCells((prev) => new Map(prev).set(o.address, { v }));
    } catch (e) {
      setCells((prev) => new Map(prev).set(o.address, { f: failureOf(e, `Read ${o.address}`, errors) }));
    }
  }

  async function writeOne(o: ObjectInfo, body: ObjectWrite): Promise<ObjectValue> {
    const v = await api.writeObject(sid, o.address, body);
    setCells((prev) => new Map(prev).set(o.address, { v }));
    return v;
  }

  const selObj = selected !== null ? (objects[selected] ?? null) : null;
  const selRow = selected !== null ? rows.indexOf(selected) : -1;

  function onSearchKey(e: KeyboardEvent<HTMLInputElement>) {
    // Arrow keys walk the result list from the search box; Enter opens the first hit.
    if (e.key === 'ArrowDown' || e.key === 'ArrowUp' || e.key === 'Enter') {
      if (rows.length === 0) return;
      e.preventDefault();
      const cur = selRow;
      const next = e.key === 'ArrowDown' ? Math.min(rows.length - 1, cur + 1) : e.key === 'ArrowUp' ? Math.max(0, cur - 1) : cur >= 0 ? cur : 0;
      setSelected(rows[next] ?? null);
    }
  }

  const header = (
    <tr>
      <th>Index</th>
      {showPnu && <th>PNU</th>}
      <th>Name</th>
      <th>Type</th>
      <th>Access</th>
      <th>PDO</th>
      <th className="num">Default</th>
      <th className="num">Min</th>
      <th className="num">Max</th>
      <th>Unit</th>
      <th className="num">Live value</th>
    </tr>
  );
  const colgroup = (
    <colgroup>
      <col style={{ width: 92 }} />
      {showPnu && <col style={{ width: 66 }} />}
      <col />
      <col style={{ width: 48 }} />
      <col style={{ width: 54 }} />
      <col style={{ width: 44 }} />
      <col style={{ width: 72 }} />
      <col style={{ width: 64 }} />
      <col style={{ width: 72 }} />
      <col style={{ width: 64 }} />
      <col style={{ width: 100 }} />
    </colgroup>
  );

  const renderRow = (r: number) => {
    const i = rows[r] as number;
    const o = objects[i] as ObjectInfo;
    const c = cells.get(o.address);
    const v = c && 'v' in c ? c.v : null;
    const differs = v ? differsFromDefault(o, v.value) : null;
    return (
      <tr
        key={i}
        className={`od-row${i === selected ? ' selected' : ''}${dirty.has(o.address) ? ' row-dirty' : ''}`}
        data-testid={`od-row-${o.address}`}
        onClick={() => setSelected(i)}
        style={{ height: ROW_HEIGHT }}
      >
        <td className="mono">{o.address}</td>
        {showPnu && <td className="mono muted">{formatPnu(o)}</td>}
        <td className="ell" title={[o.name_local, o.symbol].filter(Boolean).join(' · ') || o.name}>
          {o.symbol ? <span className="mono sym">{o.symbol}</span> : null}
          {o.name}
        </td>
        <td className="mono small" title={o.data_type}>
          {shortType(o.data_type)}
        </td>
        <td className="mono small">{o.access}</td>
        <td className="small" title={pdoText(o.pdo_mapping)}>
          {o.pdo_mapping === 'none' ? '' : o.pdo_mapping === 'both' ? 'Rx/Tx' : o.pdo_mapping.slice(0, 2).toUpperCase() === 'RX' ? 'Rx' : o.pdo_mapping.slice(0, 2).toUpperCase() === 'TX' ? 'Tx' : o.pdo_mapping}
        </td>
        <td className="mono num ell">{decText(o.default)}</td>
        <td className="mono num ell muted">{o.min ?? ''}</td>
        <td className="mono num ell muted">{o.max ?? ''}</td>
        <td className="small ell" title={o.raw_unit ? `raw: ${o.raw_unit}` : ''}>
          {o.unit ?? o.raw_unit ?? ''}
        </td>
        <td className={`mono num ell${c && 'f' in c ? ' bad' : ''}`} title={c && 'f' in c ? (c.f.meaning ?? c.f.message) : (v?.value_text ?? '')}>
          {differs ? <span className="differs-mark" title={`differs from the default ${decText(o.default)}`}>≠ </span> : null}
          {v ? decText(v.value) : c && 'f' in c ? (c.f.code_hex ?? 'error') : ''}
        </td>
      </tr>
    );
  };

  return (
    <div className="od-page">
      <div className="od-main">
        <section className="card od-tools">
          <div className="od-filters">
            <label className="od-search">
              Search
              <input
                type="search"
                data-testid="od-search"
                value={filter.query}
                placeholder="6040, 0x6040, 6040h, P24640, name, symbol, description…"
                spellCheck={false}
                autoComplete="off"
                autoFocus
                onChange={(e) => set({ query: e.target.value })}
                onKeyDown={onSearchKey}
              />
            </label>
            <label>
              Group
              <select data-testid="od-group" value={filter.group} onChange={(e) => set({ group: e.target.value })}>
                <option value="">All groups</option>
                {usedGroups.map((g) => (
                  <option key={g.id} value={g.id}>
                    {g.name}
                  </option>
                ))}
              </select>
            </label>
            <label>
              Access
              <select data-testid="od-access" value={filter.access} onChange={(e) => set({ access: e.target.value as DictionaryFilter['access'] })}>
                <option value="all">All</option>
                <option value="readable">Readable</option>
                <option value="writable">Writable</option>
              </select>
            </label>
            <label className="check">
              <input type="checkbox" data-testid="od-pdo" checked={filter.pdo} onChange={(e) => set({ pdo: e.target.checked })} /> PDO-mappable
            </label>
            <label className="check" title="Needs live values: press Read values first">
              <input type="checkbox" data-testid="od-differs" checked={filter.differs} onChange={(e) => set({ differs: e.target.checked })} /> Differs from
              default
            </label>
          </div>
          <div className="od-status">
            <span data-testid="od-count">
              {rows.length} of {objects.length} objects
            </span>
            <span className="muted small" data-testid="od-known">
              {known > 0 ? ` · ${known} with live values` : ''}
              {filter.differs && known < rows.length ? ' · the “differs” filter uses read values only: press Read values' : ''}
            </span>
            <span className="od-read">
              {reading ? (
                <>
                  <ProgressBar fraction={reading.total ? reading.done / reading.total : 0} label={`${reading.done} / ${reading.total}`} testid="od-read-progress" />
                  <button type="button" onClick={() => {
                    cancelRead.current++;
                    setReading(null);
                  }}>
                    Stop
                  </button>
                </>
              ) : (
                <button
                  type="button"
                  className="primary"
                  data-testid="od-read-values"
                  onClick={() => void readValues()}
                  disabled={rows.length === 0}
                  title={`Read the live values of the ${rows.length} filtered objects, ${READ_BATCH} per request`}
                >
                  Read values ({rows.filter((i) => isReadable(objects[i] as ObjectInfo)).length})
                </button>
              )}
            </span>
          </div>
          {readFailure && <FailureBox f={readFailure} testid="od-read-failure" />}
        </section>
        <VirtualTable
          count={rows.length}
          rowHeight={ROW_HEIGHT}
          header={header}
          colgroup={colgroup}
          renderRow={renderRow}
          className="od-table"
          testid="od-table"
          resetKey={JSON.stringify(filter)}
          scrollToRow={selRow >= 0 ? selRow : null}
          attrs={{ 'data-query': filter.query, 'data-count': String(rows.length) }}
        />
      </div>
      <aside className="card od-detail" data-testid="od-detail">
        {selObj ? (
          <Detail
            key={selObj.address}
            o={selObj}
            cell={cells.get(selObj.address) ?? null}
            groupName={selObj.group ? (groupNames.get(selObj.group) ?? selObj.group) : null}
            dirty={dirty.has(selObj.address)}
            errors={errors}
            mode={mode}
            onMode={setMode}
            onRead={() => void readOne(selObj)}
            write={(body) => writeOne(selObj, body)}
            blocked={blocked}
          />
        ) : (
          <>
            <h2>Details</h2>
            <div className="muted">Click a row (or use ↓ ↑ in the search box) to see its description, manual section and values, and to write it.</div>
          </>
        )}
      </aside>
    </div>
  );
}

function Detail({
  o,
  cell,
  groupName,
  dirty,
  errors,
  mode,
  onMode,
  onRead,
  write,
  blocked,
}: {
  o: ObjectInfo;
  cell: Cell | null;
  groupName: string | null;
  dirty: boolean;
  errors: ProfileDetail['error_list'];
  mode: NumberMode;
  onMode: (m: NumberMode) => void;
  onRead: () => void;
  write: (body: ObjectWrite) => Promise<ObjectValue>;
  blocked: string | null;
}) {
  useEffect(() => {
    // A selected object shows its live value: one read, not a batch.
    if (!cell && isReadable(o)) onRead();
    // Only when the selection changes: the component is keyed by address.
  }, []);
  const v = cell && 'v' in cell ? cell.v : null;
  const f = cell && 'f' in cell ? cell.f : null;
  const code = v ? codeInObject(o, v.value, errors) : null;
  const eng = v ? engineeringText(v, o, v.value) : null;
  const et = v ? (v.value_text ?? enumText(o, v.value)) : null;
  const differs = v ? differsFromDefault(o, v.value) : null;
  return (
    <>
      <h2 className="od-detail-head">
        <span className="mono">{o.address}</span>
        {o.pnu !== null ? <span className="mono muted">{formatPnu(o)}</span> : null}
        {o.symbol ? <span className="mono">{o.symbol}</span> : null}
      </h2>
      <div className="od-detail-name" data-testid="od-detail-name">
        {o.name}
      </div>
      {o.name_local && <div className="muted local-name-block">{o.name_local}</div>}
      <table className="kv od-kv">
        <tbody>
          <tr>
            <th>Group</th>
            <td>{groupName ?? '—'}</td>
          </tr>
          <tr>
            <th>Type · access · PDO</th>
            <td className="mono">
              {o.data_type} · {o.access} · {pdoText(o.pdo_mapping) || 'not mappable'}
            </td>
          </tr>
          <tr>
            <th>Default</th>
            <td className="mono">
              {decText(o.default)}
              {typeof o.default === 'number' && Number.isInteger(o.default) ? <span className="muted"> ({hexText(o.default, o.data_type)})</span> : null}
            </td>
          </tr>
          <tr>
            <th>Range (raw)</th>
            <td className="mono">{rangeText(o) || '—'}</td>
          </tr>
          <tr>
            <th>Unit</th>
            <td>
              {o.unit ? (
                <>
                  {o.unit} <span className="muted">= raw × {o.scale}</span>
                  {o.raw_unit ? <span className="muted"> · raw unit {o.raw_unit}</span> : null}
                </>
              ) : (
                (o.raw_unit ?? '—')
              )}
            </td>
          </tr>
          <tr>
            <th>Kept</th>
            <td>
              {o.process ? 'process value (not backed up)' : o.persist ? 'saved by Save to EEPROM' : 'not saved to non-volatile memory'}
            </td>
          </tr>
          <tr>
            <th>Manual</th>
            <td data-testid="od-detail-section">{o.section ?? '—'}</td>
          </tr>
          <tr>
            <th>Live value</th>
            <td data-testid="od-detail-value">
              {v ? (
                <>
                  <span className="mono big">{decText(v.value)}</span>
                  {v.raw_unit ? <span className="unit"> {v.raw_unit}</span> : null}
                  <span className="mono muted"> {hexText(v.value, o.data_type)}</span>
                  {eng ? <div className="mono">= {eng}</div> : null}
                  {et ? <div>“{et}”</div> : null}
                  {differs ? <div className="warn-text small">≠ differs from the default</div> : null}
                  {dirty ? <div className="small"><span className="dirty-dot">●</span> written since the last save</div> : null}
                </>
              ) : f ? (
                <FailureBox f={f} testid="od-detail-read-failure" />
              ) : isReadable(o) ? (
                <span className="muted">reading…</span>
              ) : (
                <span className="muted">write-only</span>
              )}
              {isReadable(o) && (
                <button type="button" className="small-btn od-reread" onClick={onRead}>
                  Read
                </button>
              )}
            </td>
          </tr>
        </tbody>
      </table>
      {code && <CodeInfo info={code} testid="od-detail-code" />}
      {o.description && (
        <p className="od-desc" data-testid="od-detail-description">
          {o.description}
        </p>
      )}
      {o.values && Object.keys(o.values).length > 0 && (
        <table className="grid od-enum" data-testid="od-detail-enum">
          <thead>
            <tr>
              <th className="num">Value</th>
              <th>Meaning</th>
            </tr>
          </thead>
          <tbody>
            {Object.entries(o.values)
              .sort((a, b) => Number(a[0]) - Number(b[0]))
              .map(([k, t]) => (
                <tr key={k} className={v && String(v.value) === k ? 'selected' : ''}>
                  <td className="mono num">{k}</td>
                  <td>{t}</td>
                </tr>
              ))}
          </tbody>
        </table>
      )}
      {isWritable(o) ? (
        <div className="od-write">
          <h3>Write</h3>
          <ValueEditor key={o.address} obj={o} current={v?.value} mode={mode} onMode={onMode} errors={errors} write={write} blocked={blocked} />
        </div>
      ) : (
        <div className="muted small od-write">{o.access === 'const' ? 'Constant: cannot be written.' : 'Read-only: cannot be written.'}</div>
      )}
      {isPdoMappable(o) && <div className="muted small">Mappable into a {pdoText(o.pdo_mapping)}.</div>}
    </>
  );
}
