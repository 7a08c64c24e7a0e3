/**
 * Connect: choose the bus (python-can interface, channel, bitrate), scan it for nodes
 * (identity from 1018h and the matching profile), and open or close drive sessions. The slmp
 * interface reaches a CC-Link IE TSN station (CTMM04x) by SLMP over UDP: the channel is its
 * host:port, the node id its axis + 1, and there is no scan (docs/slmp.md). The ethercat
 * interface reaches an EtherCAT line through SOEM: the channel is the network interface, the
 * node id the slave's position + 1, and Scan lists the line's slaves (docs/ethercat.md). The
 * profinet interface reaches a PROFIdrive drive (LECSN-T) by PNIO-CM record access over UDP: the channel is its IP address
 * (port 34964 unless given), the node id its DO-ID (docs/profinet.md); the DCP panel finds
 * PROFINET devices on a network interface and sets their station name and IP address.
 */
import { type FormEvent, useEffect, useState } from 'react';
import type { ProfileSummary, ScanNode, SessionInfo, SessionInterface, SessionRequest } from '../api';
import { api } from '../api/client';
import { DcpPanel } from '../components/DcpPanel';
import { StatePill } from '../components/StatePill';
import { dcpNicFromNote } from '../lib/dcp';
import { toHex } from '../lib/format';
import { SLMP_AXES, slmpAxisLabel } from '../lib/network';
import { networkState } from '../lib/nmt';
import { notify, notifyError } from '../state/notify';
import { useObservable } from '../state/observable';
import { navigate } from '../state/router';
import { refreshSessions, sessions } from '../state/store';
import { forgetControl } from '../state/control';

/** python-can interface names (python-can "Hardware interfaces"); virtual is the simulator's.
 * slmp is servodesk's SLMP link (CC-Link IE TSN), not a CAN interface. */
const INTERFACES: ReadonlyArray<{ id: SessionInterface; label: string }> = [
  { id: 'virtual', label: 'virtual (in-process simulator)' },
  { id: 'udp_multicast', label: 'udp_multicast (simulator in another process)' },
  { id: 'socketcan', label: 'socketcan (Linux CAN)' },
  { id: 'pcan', label: 'pcan (PEAK-System)' },
  { id: 'kvaser', label: 'kvaser' },
  { id: 'ixxat', label: 'ixxat (HMS)' },
  { id: 'vector', label: 'vector' },
  { id: 'slcan', label: 'slcan (serial-line CAN)' },
  { id: 'gs_usb', label: 'gs_usb (candleLight)' },
  { id: 'slmp', label: 'slmp (CC-Link IE TSN station, SLMP over UDP)' },
  { id: 'profinet', label: 'profinet (PROFINET IO device, PROFIdrive over UDP)' },
  { id: 'ethercat', label: 'ethercat (EtherCAT line on a network interface, SOEM)' },
];

/** 004 §20.1.3: the IP address comes from the master, DHCP or the rotary switches (4th octet);
 * the manual prints no default, so this is an example. Port 34964 is PNIO-CM's. */
const PROFINET_DEFAULT_CHANNEL = '192.168.0.10';

/** 003 §1-3: the unit's IP address is 192.168.0.250 by default; the port is not in the manual
 * (5010 is MR-J4-GF's SLMP port, servodesk's default). */
const SLMP_DEFAULT_CHANNEL = '192.168.0.250:5010';

const DEFAULT_CHANNEL: Readonly<Record<string, string>> = {
  virtual: 'servodesk-sim',
  udp_multicast: '239.74.163.2',
  socketcan: 'can0',
  pcan: 'PCAN_USBBUS1',
  kvaser: '0',
  ixxat: '0',
  vector: '0',
  slcan: '/dev/ttyACM0',
  gs_usb: '0',
  slmp: SLMP_DEFAULT_CHANNEL,
  profinet: PROFINET_DEFAULT_CHANNEL,
  ethercat: 'eth1',
};

// CiA 301 §7.2 / CiA 102 bit timing table: the standard CANopen bitrates.
const BITRATES: readonly number[] = [1_000_000, 800_000, 500_000, 250_000, 125_000, 50_000, 20_000, 10_000];

function formatBitrate(b: number | null): string {
  if (b === null) return '—';
  return b >= 1_000_000 ? `${b / 1_000_000} Mbit/s` : `${b / 1000} kbit/s`;
}

function hexOrDash(v: number | null | undefined): string {
  return v === null || v === undefined ? '—' : toHex(v, 'UNSIGNED32');
}

/** The interface serve --sim's PROFINET twin answers DCP behind, from its session's note. */
function dcpNicFromNotes(list: SessionInfo[] | null): string | null {
  for (const s of list ?? []) {
    const nic = dcpNicFromNote(s.note);
    if (nic) return nic;
  }
  return null;
}

interface BusForm {
  interface: SessionInterface;
  channel: string;
  bitrate: string;
  nodeId: string;
  profile: string;
}

export function ConnectPage() {
  const [form, setForm] = useState<BusForm>({
    interface: 'virtual',
    channel: DEFAULT_CHANNEL.virtual ?? '',
    bitrate: '',
    nodeId: '5',
    profile: '',
  });
  const [profiles, setProfiles] = useState<ProfileSummary[] | null>(null);
  const [scan, setScan] = useState<ScanNode[] | null>(null);
  const [busy, setBusy] = useState<'scan' | 'open' | null>(null);
  const [formError, setFormError] = useState<string | null>(null);
  const list = useObservable(sessions);

  useEffect(() => {
    let live = true;
    api.profiles().then(
      (p) => live && setProfiles(p),
      (e: unknown) => live && notifyError(e),
    );
    return () => {
      live = false;
    };
  }, []);

  const slmp = form.interface === 'slmp';
  const ethercat = form.interface === 'ethercat';
  const profinet = form.interface === 'profinet';
  /** Not a CAN bus: no bitrate and no scan. */
  const ethernet = slmp || ethercat || profinet;
  const needsBitrate = !ethernet && form.interface !== 'virtual' && form.interface !== 'udp_multicast';
  const bitrate = form.bitrate === '' ? null : Number(form.bitrate);

  function set<K extends keyof BusForm>(key: K, value: BusForm[K]) {
    setForm((f) => {
      const next = { ...f, [key]: value };
      if (key === 'interface') {
        next.channel = DEFAULT_CHANNEL[next.interface] ?? '';
        if (next.interface === 'slmp' || next.interface === 'ethercat' || next.interface === 'profinet') next.bitrate = '';
        if (next.interface === 'profinet') next.nodeId = '1'; // The LECSN-T's DO-ID (P975.7).
        if (next.interface === 'slmp') {
          if (Number(next.nodeId) > SLMP_AXES.length) next.nodeId = '1';
        }
      }
      return next;
    });
  }

  async function doScan() {
    if (form.interface === 'slmp' || form.interface === 'profinet') return; // Button disabled.
    const iface = form.interface;
    setBusy('scan');
    setScan(null);
    try {
      const res = await api.scan({ interface: iface, channel: form.channel.trim(), bitrate, timeout: 0.5 });
      setScan(res.nodes);
      if (res.nodes.length === 0) {
        notify({
          kind: 'warning',
          title: 'Scan found no node',
          message: `no node answered on ${form.interface}:${form.channel}`,
          detail: null,
          hint: 'check the channel, the bitrate, the termination and that the drive is powered',
        });
      }
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  }

  async function open(req: SessionRequest) {
    setBusy('open');
    try {
      const s = await api.openSession(req);
      await refreshSessions();
      navigate('overview', s.id);
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  }

  function onSubmit(e: FormEvent) {
    e.preventDefault();
    const node = Number(form.nodeId);
    if (slmp && !(Number.isInteger(node) && node >= 1 && node <= SLMP_AXES.length)) {
      setFormError('the axis must be X, Y, Z or U (node id 1 to 4; 003 §4-2)');
      return;
    }
    if (!Number.isInteger(node) || node < 1 || node > 127) {
      setFormError('node id must be a whole number from 1 to 127 (CiA 301 §7.3.3)');
      return;
    }
    if (!form.channel.trim()) {
      setFormError(
        slmp
          ? `enter the station's address as host:port (e.g. ${SLMP_DEFAULT_CHANNEL})`
          : ethercat
            ? 'enter the network interface the EtherCAT line is plugged into (e.g. eth1)'
            : profinet
              ? `enter the drive's IP address, or host:port (e.g. ${PROFINET_DEFAULT_CHANNEL})`
              : 'enter a channel (e.g. servodesk-sim for the simulator, can0 for socketcan)',
      );
      return;
    }
    setFormError(null);
    void open({
      interface: form.interface,
      channel: form.channel.trim(),
      bitrate,
      node_id: node,
      profile: form.profile || null,
    });
  }

  async function close(s: SessionInfo) {
    try {
      await api.closeSession(s.id);
      // A closed session is held by nobody: the tab's token forgets it.
      forgetControl(s.id);
      await refreshSessions();
      notify({ kind: 'info', title: `Closed ${s.id}`, message: '', detail: null, hint: null });
    } catch (e) {
      notifyError(e);
    }
  }

  return (
    <div className="stack">
      <section className="card">
        <h2>Bus</h2>
        <form className="form-grid" onSubmit={onSubmit} data-testid="connect-form">
          <label>
            Interface
            <select
              data-testid="bus-interface"
              value={form.interface}
              onChange={(e) => {
                setScan(null); // The nodes found were on the other bus.
                set('interface', e.target.value as SessionInterface);
              }}
            >
              {INTERFACES.map((i) => (
                <option key={i.id} value={i.id}>
                  {i.label}
                </option>
              ))}
            </select>
          </label>
          <label>
            {slmp ? 'Station (host:port)' : ethercat ? 'Network interface' : profinet ? 'Device (IP or host:port)' : 'Channel'}
            <input
              data-testid="bus-channel"
              className="mono"
              value={form.channel}
              onChange={(e) => set('channel', e.target.value)}
              spellCheck={false}
            />
          </label>
          <label>
            Bitrate
            <select
              data-testid="bus-bitrate"
              value={form.bitrate}
              onChange={(e) => set('bitrate', e.target.value)}
              disabled={ethernet}
            >
              <option value="">
                {ethernet ? 'not used (Ethernet)' : needsBitrate ? 'interface default' : 'not used (virtual bus)'}
              </option>
              {BITRATES.map((b) => (
                <option key={b} value={b}>
                  {formatBitrate(b)}
                </option>
              ))}
            </select>
          </label>
          {slmp ? (
            <label title="003 §4-2: SLMP addresses an axis by the frame's multidrop station no. (0 = X ... 3 = U)">
              Axis
              <select data-testid="bus-node-id" value={form.nodeId} onChange={(e) => set('nodeId', e.target.value)}>
                {SLMP_AXES.map((a, i) => (
                  <option key={a} value={String(i + 1)}>
                    {slmpAxisLabel(i + 1)}
                  </option>
                ))}
              </select>
            </label>
          ) : (
            <label
              title={
                ethercat
                  ? 'The slave position in the line + 1 (1 = the first slave after the master)'
                  : profinet
                    ? "The drive object's DO-ID: 1 on the LECSN-T (P975.7, 004 §20.4.3.7)"
                    : undefined
              }
            >
              {ethercat ? 'Slave (position + 1)' : profinet ? 'DO-ID' : 'Node id'}
              <input
                data-testid="bus-node-id"
                className="mono narrow"
                type="number"
                min={1}
                max={127}
                value={form.nodeId}
                onChange={(e) => set('nodeId', e.target.value)}
              />
            </label>
          )}
          <label className="wide">
            Profile
            <select data-testid="bus-profile" value={form.profile} onChange={(e) => set('profile', e.target.value)}>
              <option value="">auto-detect from 1018h (identity)</option>
              {(profiles ?? []).map((p) => (
                <option key={p.id} value={p.id}>
                  {p.name} — {p.fieldbus} ({p.id})
                </option>
              ))}
            </select>
          </label>
          <div className="form-actions">
            <button
              type="button"
              data-testid="scan-bus"
              onClick={() => void doScan()}
              disabled={busy !== null || slmp || profinet}
              title={
                slmp
                  ? 'SLMP has no scan: enter the station and the axis, then open the session'
                  : ethercat
                    ? 'Find the slaves of the line on this network interface (SOEM config_init) and read their identity'
                    : profinet
                      ? 'PROFINET devices are found by DCP: search a network interface below, or enter the IP address'
                      : undefined
              }
            >
              {busy === 'scan' ? 'Scanning…' : 'Scan bus'}
            </button>
            <button type="submit" className="primary" data-testid="open-session" disabled={busy !== null}>
              {busy === 'open' ? 'Opening…' : 'Open session'}
            </button>
          </div>
          {formError && (
            <div className="inline-error wide" data-testid="connect-form-error">
              {formError}
            </div>
          )}
        </form>
      </section>

      {profinet && (
        <DcpPanel
          key={dcpNicFromNotes(list) ?? 'eth1'}
          defaultNic={dcpNicFromNotes(list) ?? 'eth1'}
          onUse={(channel) => {
            set('channel', channel);
            set('nodeId', '1');
          }}
        />
      )}

      {scan !== null && (
        <section className="card">
          <h2>
            {ethercat ? 'Slaves' : 'Nodes'} on {form.interface}:{form.channel} <span className="muted">({scan.length})</span>
          </h2>
          <table className="grid" data-testid="scan-results">
            <thead>
              <tr>
                <th>{ethercat ? 'Slave' : 'Node'}</th>
                <th>Vendor id</th>
                <th>Product code</th>
                <th>Revision</th>
                <th>Serial</th>
                <th>Device name</th>
                <th>Detected profile</th>
                <th />
              </tr>
            </thead>
            <tbody>
              {scan.map((n) => (
                <tr key={n.node_id} data-testid={`scan-node-${n.node_id}`}>
                  <td className="mono num">{n.node_id}</td>
                  <td className="mono">{hexOrDash(n.vendor_id)}</td>
                  <td className="mono">{hexOrDash(n.product_code)}</td>
                  <td className="mono">{hexOrDash(n.revision)}</td>
                  <td className="mono">{hexOrDash(n.serial)}</td>
                  <td>{n.device_name ?? <span className="muted">identity not readable</span>}</td>
                  <td>{n.profile_id ?? <span className="muted">no profile matches; pick one above</span>}</td>
                  <td className="actions">
                    {n.session_id ? (
                      <button
                        type="button"
                        data-testid={`scan-open-${n.node_id}`}
                        title={`already open as ${n.session_id}`}
                        onClick={() => navigate('overview', n.session_id)}
                      >
                        Go to session
                      </button>
                    ) : (
                      <button
                        type="button"
                        className="primary"
                        data-testid={`scan-open-${n.node_id}`}
                        disabled={busy !== null}
                        onClick={() =>
                          void open({
                            interface: form.interface,
                            channel: form.channel.trim(),
                            bitrate,
                            node_id: n.node_id,
                            profile: n.profile_id ?? (form.profile || null),
                          })
                        }
                      >
                        Open
                      </button>
                    )}
                  </td>
                </tr>
              ))}
            </tbody>
          </table>
        </section>
      )}

      <section className="card">
        <h2>
          Open sessions <span className="muted">({list?.length ?? '…'})</span>
        </h2>
        {list === null ? (
          <div className="muted">loading…</div>
        ) : list.length === 0 ? (
          <div className="empty">No session is open. Scan the bus or open a node above.</div>
        ) : (
          <div className="table-scroll">
            <table className="grid" data-testid="sessions">
              <thead>
                <tr>
                  <th title="the session, and the drive profile it was opened with">Session · profile</th>
                  <th>Node</th>
                  <th title="the drive's fieldbus, and the bus servodesk reaches it on">Fieldbus · bus</th>
                  <th>State</th>
                  <th title="NMT on CANopen; what the fieldbus has instead elsewhere (EtherCAT AL state, PROFINET AR, SLMP link)">Network state</th>
                  <th>Note</th>
                  <th />
                </tr>
              </thead>
              <tbody>
                {list.map((s) => (
                  <tr key={s.id} data-testid={`session-row-${s.id}`} data-profile={s.profile_id}>
                    <td className="mono nowrap">
                      {s.id}
                      {s.simulated && (
                        <span className="badge badge-sim" title="a simulated twin, not a real drive">
                          SIM
                        </span>
                      )}
                      {!s.connected && <span className="badge badge-bad">disconnected</span>}
                      <div className="small muted profile-name" title={s.profile_id}>
                        {s.profile_name}
                      </div>
                    </td>
                    <td className="mono num">{s.node_id}</td>
                    <td>
                      {s.fieldbus}
                      <div className="mono nowrap small muted">
                        {s.interface}:{s.channel}
                        {s.bitrate ? ` @ ${formatBitrate(s.bitrate)}` : ''}
                      </div>
                    </td>
                    <td>
                      <StatePill state={s.state} testid={`session-state-${s.id}`} />
                    </td>
                    <td className="mono" title={networkState(s).title} data-testid={`session-nmt-${s.id}`}>
                      {networkState(s).label} {networkState(s).value}
                    </td>
                    <td className="note">
                      <span className="clamp" title={s.note ?? ''}>
                        {s.note ?? ''}
                      </span>
                    </td>
                    <td className="actions">
                      <button type="button" className="primary" data-testid={`session-open-${s.id}`} onClick={() => navigate('overview', s.id)}>
                        Open
                      </button>
                      <button type="button" data-testid={`session-close-${s.id}`} onClick={() => void close(s)}>
                        Close
                      </button>
                    </td>
                  </tr>
                ))}
              </tbody>
            </table>
          </div>
        )}
      </section>
    </div>
  );
}
