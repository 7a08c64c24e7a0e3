/**
 * Network configuration: the "network configuration" page of the LEC-S-NP PROFINET card web
 * server (LECSN manual 004 §20.7), for every drive family, from the profile's `network:`
 * section (docs/profiles.md). The session's link (fieldbus, interface, channel, node id or SLMP
 * axis, NMT state); how the family is addressed, each rule with its manual section; the
 * objects that configure or report the network, read live through POST .../read (raw and hex
 * side by side with the engineering value, as on the Parameters page; an object the drive
 * refuses shows the refusal in its row); and the LED decode the manual gives.
 */
import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import type { DcpDevice, NetworkInfo, ObjectValue, SessionInfo } from '../api';
import { api } from '../api/client';
import { FailureBox } from '../components/FailureBox';
import { type Failure, failureOf, failureOfBody } from '../lib/codes';
import { canonicalAddress, formatPnu } from '../lib/dictionary';
import { type LedGroup, type NetworkRow, ledGroups, networkAddresses, networkRows, slmpAxisLabel } from '../lib/network';
import { dcpNicFromNote, hex4 } from '../lib/dcp';
import { networkState } from '../lib/nmt';
import { decText, engineeringText, enumText, hexText, isObjectValue } from '../lib/values';
import { useSessionInfo, useSessionProfile } from '../state/profileCache';
import './dataPages.css';
import type { PageProps } from './registry';

type Cell = { v: ObjectValue } | { f: Failure };

function LinkCard({ session }: { session: SessionInfo }) {
  const slmp = session.interface === 'slmp';
  const profinet = session.interface === 'profinet';
  const link = session.link ?? session.fieldbus;
  const net = networkState(session);
  return (
    <section className="card" data-testid="network-link">
      <h2>
        Link <span className="h2-side muted">this session</span>
      </h2>
      <table className="kv">
        <tbody>
          <tr>
            <th>Fieldbus (profile)</th>
            <td className="mono" data-testid="network-fieldbus">
              {session.fieldbus}
            </td>
          </tr>
          <tr>
            <th>Link</th>
            <td className="mono" data-testid="network-link-name">
              {link}
            </td>
          </tr>
          {session.ar && (
            <tr>
              <th>Application relation</th>
              <td data-testid="network-ar" title="docs/profinet.md: which AR servodesk uses">
                {session.ar}
              </td>
            </tr>
          )}
          <tr>
            <th>Interface</th>
            <td className="mono" data-testid="network-interface">
              {session.interface}
            </td>
          </tr>
          <tr>
            <th>{slmp ? 'Station (host:port)' : profinet ? 'Device (host:port)' : 'Channel'}</th>
            <td className="mono" data-testid="network-channel">
              {session.channel}
              {session.bitrate ? <span className="muted"> · {session.bitrate / 1000} kbit/s</span> : null}
            </td>
          </tr>
          {slmp ? (
            <tr>
              <th title="003 §4-2: SLMP addresses an axis by the frame's multidrop station no. (0 = X ... 3 = U); docs/slmp.md">Axis</th>
              <td className="mono" data-testid="network-axis">
                {slmpAxisLabel(session.node_id)}
              </td>
            </tr>
          ) : (
            <tr>
              <th title={profinet ? "The drive object's DO-ID (P975.7, 004 §20.4.3.7)" : undefined}>
                {profinet ? 'DO-ID' : 'Node id'}
              </th>
              <td className="mono" data-testid="network-node-id">
                {session.node_id}
              </td>
            </tr>
          )}
          <tr>
            <th data-testid="network-nmt-label">{net.label === 'NMT' ? 'NMT state' : net.label}</th>
            <td className="mono" data-testid="network-nmt" title={net.title}>
              {net.value}
            </td>
          </tr>
        </tbody>
      </table>
      {session.note && (
        <div className="sim-note" data-testid="network-note">
          {session.simulated && <span className="badge badge-sim">SIM</span>}
          {session.note}
        </div>
      )}
    </section>
  );
}

/** The drive's station name and IP suite as it reports them over DCP (the card web server's
 * "Network configuration" page shows the same, 004 §20.7): found among the devices answering
 * on a network interface by this session's address. */
function DcpCard({ session }: { session: SessionInfo }) {
  const [nic, setNic] = useState(dcpNicFromNote(session.note) ?? 'eth1');
  const [found, setFound] = useState<{ dev: DcpDevice | null; n: number } | null>(null);
  const [fail, setFail] = useState<Failure | null>(null);
  const [busy, setBusy] = useState(false);

  async function read() {
    setBusy(true);
    setFail(null);
    try {
      const res = await api.dcpIdentify({ nic: nic.trim(), timeout: 1.0 });
      // By the session the server matched (IP and port), else by the IP address alone: a
      // device whose PNIO-CM port is not 34964 is matched by its address on the segment.
      const host = session.channel.replace(/:\d+$/, '');
      const dev = res.devices.find((d) => d.session_id === session.id) ?? res.devices.find((d) => d.ip === host) ?? null;
      setFound({ dev, n: res.devices.length });
    } catch (e) {
      setFound(null);
      setFail(failureOf(e, `Search ${nic.trim()} by DCP`));
    } finally {
      setBusy(false);
    }
  }

  const d = found?.dev;
  return (
    <section className="card" data-testid="network-dcp">
      <h2>
        Station name and address <span className="h2-side muted">DCP · 004 §20.1.3</span>
      </h2>
      <form
        className="network-dcp-form"
        onSubmit={(e) => {
          e.preventDefault();
          void read();
        }}
      >
        <input
          data-testid="network-dcp-nic"
          className="mono"
          aria-label="Network interface"
          title="The network interface the drive is cabled to, as `ip link` names it"
          value={nic}
          onChange={(e) => setNic(e.target.value)}
          spellCheck={false}
        />
        <button type="submit" data-testid="network-dcp-read" disabled={busy || nic.trim() === ''}>
          {busy ? 'Searching…' : 'Read by DCP'}
        </button>
      </form>
      {fail && <FailureBox f={fail} testid="network-dcp-failure" />}
      {found && !d && (
        <p className="muted" data-testid="network-dcp-missing">
          None of the {found.n} device(s) answering on {nic} is at this session&apos;s address.
        </p>
      )}
      {d && (
        <table className="kv" data-testid="network-dcp-table">
          <tbody>
            <tr>
              <th>Station name</th>
              <td className="mono" data-testid="network-dcp-name">
                {d.name_of_station || <span className="badge badge-warn">not set</span>}
              </td>
            </tr>
            <tr>
              <th>MAC address</th>
              <td className="mono">{d.mac}</td>
            </tr>
            <tr>
              <th>IP address</th>
              <td className="mono" data-testid="network-dcp-ip">
                {d.ip} <span className="muted">({d.ip_origin})</span>
                {d.ip_conflict && <span className="badge badge-bad">address conflict</span>}
              </td>
            </tr>
            <tr>
              <th>Subnet mask</th>
              <td className="mono">{d.netmask}</td>
            </tr>
            <tr>
              <th>Gateway</th>
              <td className="mono">{d.gateway}</td>
            </tr>
            <tr>
              <th title="PROFINET vendor ID / device ID (the GSDML file's)">Vendor / device ID</th>
              <td className="mono">
                {hex4(d.vendor_id)} / {hex4(d.device_id)}
              </td>
            </tr>
            <tr>
              <th>Type</th>
              <td>{d.type_of_station}</td>
            </tr>
          </tbody>
        </table>
      )}
      <p className="muted small">
        Changed from the Connect page (PROFINET devices): the drive refuses a new name or address while this session is open.
      </p>
    </section>
  );
}

function AddressingCard({ network }: { network: NetworkInfo }) {
  return (
    <section className="card" data-testid="network-addressing">
      <h2>
        Addressing <span className="h2-side muted">{network.section}</span>
      </h2>
      <p className="network-summary" data-testid="network-summary">
        {network.summary}
      </p>
      {network.addressing.length > 0 && (
        <ul className="network-rules">
          {network.addressing.map((r) => (
            <li key={r.text} data-testid="network-rule">
              {r.text} <span className="muted small nowrap">{r.section}</span>
            </li>
          ))}
        </ul>
      )}
    </section>
  );
}

function ValueCells({ row, cell }: { row: NetworkRow; cell: Cell | undefined }) {
  const o = row.object;
  if (!o) {
    return (
      <td colSpan={3} className="bad small">
        not an object of the profile
      </td>
    );
  }
  if (cell && 'f' in cell) {
    const f = cell.f;
    return (
      <td colSpan={3} className="bad small" data-testid="network-refused" title={[f.message, f.hint].filter(Boolean).join('\n')}>
        {f.code_hex ? <span className="mono">{f.code_hex} </span> : null}
        {f.meaning ?? f.message}
      </td>
    );
  }
  const v = cell?.v ?? null;
  const eng = v ? engineeringText(v, o, v.value) : null;
  const text = v ? (v.value_text ?? enumText(o, v.value)) : null;
  // An enumeration text that starts with the engineering value says it already ("1000 kbit/s
  // (default)"): one of the two is enough.
  const meaning = [text && eng && text.startsWith(eng) ? null : eng, text].filter(Boolean).join(' · ');
  return (
    <>
      <td className="mono num nowrap" data-testid="network-value">
        {v ? decText(v.value) : '…'}
        {v?.raw_unit ? <span className="unit"> {v.raw_unit}</span> : null}
      </td>
      <td className="mono num nowrap muted" data-testid="network-hex">
        {v ? hexText(v.value, o.data_type) : ''}
      </td>
      <td className="small" data-testid="network-meaning">
        {meaning}
      </td>
    </>
  );
}

function LedCard({ leds }: { leds: readonly LedGroup[] }) {
  return (
    <section className="card" data-testid="network-leds">
      <h2>
        LEDs <span className="h2-side muted">as the manual decodes them</span>
      </h2>
      <table className="grid network-leds">
        <thead>
          <tr>
            <th>LED</th>
            <th>State</th>
            <th>Meaning</th>
            <th>Section</th>
          </tr>
        </thead>
        <tbody>
          {leds.flatMap((g) =>
            g.states.map((l, i) => (
              <tr key={`${g.led}/${l.state}`} data-testid="network-led">
                {i === 0 && (
                  <th rowSpan={g.states.length} scope="rowgroup" className="network-led-name">
                    {g.led}
                  </th>
                )}
                <td className="network-led-state">{l.state}</td>
                <td>{l.meaning}</td>
                <td className="muted small network-led-section">{l.section}</td>
              </tr>
            )),
          )}
        </tbody>
      </table>
    </section>
  );
}

export function NetworkPage({ sid }: PageProps) {
  const { info } = useSessionInfo(sid);
  const { profile, error: profileError } = useSessionProfile(info);
  const rows = useMemo(() => (profile ? networkRows(profile) : []), [profile]);
  const leds = useMemo(() => ledGroups(profile?.network?.leds ?? []), [profile]);
  const [cells, setCells] = useState<Map<string, Cell>>(new Map());
  const [reading, setReading] = useState(false);
  const readToken = useRef(0);

  const read = useCallback(async () => {
    const addrs = networkAddresses(rows);
    if (!addrs.length) return;
    const token = ++readToken.current;
    const errors = profile?.error_list ?? [];
    setReading(true);
    try {
      const res = await api.readMany(sid, addrs);
      if (token !== readToken.current) return;
      const next = new Map<string, Cell>();
      res.results.forEach((r, i) => {
        const addr = canonicalAddress(r.address ?? addrs[i] ?? '');
        if (isObjectValue(r)) next.set(addr, { v: r });
        else if ('error' in r) next.set(addr, { f: failureOfBody(r.error, `Read ${addr}`, errors) });
      });
      setCells(next);
    } catch (e) {
      if (token !== readToken.current) return;
      // The whole request failed (the session closed, the link is down): every row says so.
      const f = failureOf(e, `Read ${addrs.length} objects`, errors);
      setCells(new Map(addrs.map((a) => [a, { f }] as const)));
    } finally {
      if (token === readToken.current) setReading(false);
    }
  }, [sid, rows, profile]);

  useEffect(() => {
    void read();
  }, [read]);

  if (profileError) return <FailureBox f={failureOf(profileError, 'Load the profile')} />;
  if (!info || !profile) return <div className="muted">Loading the profile…</div>;

  const network = profile.network ?? null;
  const showPnu = rows.some((r) => r.object?.pnu !== null && r.object?.pnu !== undefined);

  const objectsCard =
    network && rows.length > 0 ? (
      <section className="card" data-testid="network-objects">
        <h2>
          Network objects
          <span className="h2-side">
            <button type="button" className="small-btn" data-testid="network-reload" disabled={reading} onClick={() => void read()}>
              {reading ? 'Reading…' : 'Read again'}
            </button>
          </span>
        </h2>
        <table className="grid network-table">
          <thead>
            <tr>
              <th>Object</th>
              <th>Name · what it tells</th>
              <th className="num" title="The value as the drive holds it, in its raw unit">
                Raw value
              </th>
              <th className="num">Hex</th>
              <th title="Raw value × scale in engineering units, or the value's meaning">Engineering · meaning</th>
            </tr>
          </thead>
          <tbody>
            {rows.map((r) => {
              const addr = canonicalAddress(r.entry.address);
              const o = r.object;
              return (
                <tr key={addr} data-testid={`network-row-${addr}`}>
                  <td className="mono nowrap">
                    {addr}
                    {showPnu && o?.pnu != null ? <div className="muted small">{formatPnu(o)}</div> : null}
                  </td>
                  <td className="network-note">
                    <div className="network-name" title={[o?.name_local, o?.data_type, o?.description].filter(Boolean).join('\n')}>
                      {o?.name ?? '—'}
                    </div>
                    <div className="muted">
                      {r.entry.note} <span className="nowrap">({r.entry.section})</span>
                    </div>
                  </td>
                  <ValueCells row={r} cell={cells.get(addr)} />
                </tr>
              );
            })}
          </tbody>
        </table>
      </section>
    ) : null;

  return (
    <div className="stack network-page">
      <div className="network-top">
        {info.interface === 'profinet' ? (
          <div className="stack">
            <LinkCard session={info} />
            <DcpCard session={info} />
          </div>
        ) : (
          <LinkCard session={info} />
        )}
        {objectsCard ??
          (network ? (
            <AddressingCard network={network} />
          ) : (
            <section className="card" data-testid="network-none">
              <h2>Addressing</h2>
              <p className="muted">
                The profile <span className="mono">{profile.id}</span> documents no network section: servodesk knows nothing of how this
                family is addressed beyond the link shown here.
              </p>
            </section>
          ))}
      </div>

      {objectsCard && network && (
        <div className={leds.length ? 'overview-grid' : 'stack'}>
          <AddressingCard network={network} />
          {leds.length > 0 && <LedCard leds={leds} />}
        </div>
      )}
      {!objectsCard && network && leds.length > 0 && <LedCard leds={leds} />}
    </div>
  );
}
