/**
 * PROFINET devices on a network interface, found by DCP Identify, with what an engineer does
 * with a new drive (docs/profinet.md, "DCP"): give it a station name and an IP address (004
 * §20.1.3), flash its LED to find it in the cabinet (the Network Status LED blinks green,
 * §20.2.3), reset it to factory settings (options 2 and 8, §20.4.5), and open a session at its
 * address. DCP is layer 2: the server needs root or CAP_NET_RAW, and says so otherwise.
 */
import { type FormEvent, useState } from 'react';
import type { DcpDevice } from '../api';
import { api } from '../api/client';
import { notify, notifyError } from '../state/notify';
import { navigate } from '../state/router';
import { hex4, nameProblem } from '../lib/dcp';
import { ConfirmDialog } from './ConfirmDialog';

interface EditForm {
  mac: string;
  name: string;
  ip: string;
  netmask: string;
  gateway: string;
  permanent: boolean;
}

export function DcpPanel({ defaultNic, onUse }: { defaultNic: string; onUse: (channel: string) => void }) {
  const [nic, setNic] = useState(defaultNic);
  const [devices, setDevices] = useState<DcpDevice[] | null>(null);
  const [busy, setBusy] = useState<string | null>(null);
  const [edit, setEdit] = useState<EditForm | null>(null);
  const [reset, setReset] = useState<{ mac: string; mode: 2 | 8 } | null>(null);

  async function search(quiet = false) {
    setBusy('search');
    try {
      const res = await api.dcpIdentify({ nic: nic.trim(), timeout: 1.0 });
      setDevices(res.devices);
      if (!quiet && res.devices.length === 0) {
        notify({
          kind: 'warning',
          title: 'No PROFINET device answered',
          message: `no DCP answer on ${res.nic} within 1 s`,
          detail: null,
          hint: 'check the cable and the interface; a drive answers DCP as soon as it is powered',
        });
      }
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  }

  async function flash(mac: string) {
    setBusy(mac);
    try {
      await api.dcpSignal(nic.trim(), mac);
      notify({ kind: 'info', title: `LED of ${mac} flashing`, message: 'look for the green blinking Network Status LED', detail: null, hint: null });
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  }

  async function submit(e: FormEvent) {
    e.preventDefault();
    if (edit === null) return;
    const dev = devices?.find((d) => d.mac === edit.mac);
    const name = edit.name.trim();
    const nameChanged = name !== '' && name !== (dev?.name_of_station ?? '');
    const ipChanged =
      edit.ip.trim() !== (dev?.ip ?? '') ||
      edit.netmask.trim() !== (dev?.netmask ?? '') ||
      edit.gateway.trim() !== (dev?.gateway ?? '');
    if (!nameChanged && !ipChanged) {
      setEdit(null);
      return;
    }
    setBusy(edit.mac);
    try {
      const done = await api.dcpSet({
        nic: nic.trim(),
        mac: edit.mac,
        name_of_station: nameChanged ? name : null,
        ip: ipChanged ? { ip: edit.ip.trim(), netmask: edit.netmask.trim(), gateway: edit.gateway.trim() || '0.0.0.0' } : null,
        permanent: edit.permanent,
      });
      notify({ kind: 'info', title: `Set ${done.mac}`, message: done.done.join(', ').replace('_', ' '), detail: null, hint: null });
      setEdit(null);
      await search(true);
    } catch (err) {
      notifyError(err);
    } finally {
      setBusy(null);
    }
  }

  async function doReset() {
    if (reset === null) return;
    setBusy(reset.mac);
    try {
      await api.dcpReset(nic.trim(), reset.mac, reset.mode);
      notify({
        kind: 'warning',
        title: `${reset.mac} reset to factory (option ${reset.mode})`,
        message: 'its station name is "" and its IP address 0.0.0.0: set them before opening a session',
        detail: null,
        hint: null,
      });
      setReset(null);
      await search(true);
    } catch (e) {
      notifyError(e);
    } finally {
      setBusy(null);
    }
  }

  const nameError = edit ? nameProblem(edit.name.trim()) : null;

  return (
    <section className="card" data-testid="dcp-panel">
      <h2>
        PROFINET devices (DCP) {devices !== null && <span className="muted">({devices.length})</span>}
      </h2>
      <form
        className="form-grid"
        onSubmit={(e) => {
          e.preventDefault();
          void search();
        }}
      >
        <label title="The network interface the drives are cabled to, as `ip link` names it">
          Network interface
          <input data-testid="dcp-nic" className="mono" value={nic} onChange={(e) => setNic(e.target.value)} spellCheck={false} />
        </label>
        <div className="form-actions">
          <button type="submit" data-testid="dcp-search" disabled={busy !== null || nic.trim() === ''}>
            {busy === 'search' ? 'Searching…' : 'Search (DCP Identify)'}
          </button>
        </div>
      </form>
      {devices !== null && devices.length > 0 && (
        <div className="table-scroll">
          <table className="grid" data-testid="dcp-results">
            <thead>
              <tr>
                <th>MAC</th>
                <th>Station name</th>
                <th>IP address / mask · gateway</th>
                <th title="PROFINET vendor ID / device ID (from the device's GSDML file)">Vendor / device</th>
                <th>Type</th>
                <th />
              </tr>
            </thead>
            <tbody>
              {devices.map((d) => (
                <tr key={d.mac} data-testid={`dcp-device-${d.mac}`}>
                  <td className="mono">{d.mac}</td>
                  <td data-testid="dcp-name">
                    {d.name_of_station ? (
                      <span className="mono">{d.name_of_station}</span>
                    ) : (
                      <span className="badge badge-warn" title="Network Status LED: red single flash (004 §20.2.3)">
                        no name
                      </span>
                    )}
                  </td>
                  <td data-testid="dcp-ip">
                    {d.ip && d.ip !== '0.0.0.0' ? (
                      <>
                        <span className="mono">
                          {d.ip}/{d.netmask}
                        </span>{' '}
                        <span className="muted">
                          · {d.gateway} ({d.ip_origin})
                        </span>
                        {d.ip_conflict && <span className="badge badge-bad">address conflict</span>}
                      </>
                    ) : (
                      <span className="badge badge-warn" title="Network Status LED: red double flash (004 §20.2.3)">
                        no address
                      </span>
                    )}
                  </td>
                  <td className="mono">
                    {hex4(d.vendor_id)} / {hex4(d.device_id)}
                  </td>
                  <td>
                    {d.type_of_station ?? '—'}
                    {d.profile_id && (
                      <div className="small muted" data-testid="dcp-profile" title="The profile whose vendor and device ID these are">
                        profile {d.profile_id}
                      </div>
                    )}
                  </td>
                  <td className="actions">
                    {d.session_id ? (
                      <button type="button" data-testid="dcp-go" onClick={() => navigate('overview', d.session_id)}>
                        Go to session
                      </button>
                    ) : (
                      <button
                        type="button"
                        className="primary"
                        data-testid="dcp-use"
                        disabled={d.channel === null}
                        title={d.channel === null ? 'set an IP address first' : `put ${d.channel} in the form above`}
                        onClick={() => d.channel !== null && onUse(d.channel)}
                      >
                        Use address
                      </button>
                    )}
                    <button type="button" data-testid="dcp-flash" disabled={busy !== null} onClick={() => void flash(d.mac)}>
                      Flash LED
                    </button>
                    <button
                      type="button"
                      data-testid="dcp-edit"
                      disabled={busy !== null}
                      onClick={() =>
                        setEdit({
                          mac: d.mac,
                          name: d.name_of_station ?? '',
                          ip: d.ip && d.ip !== '0.0.0.0' ? d.ip : '',
                          netmask: d.netmask && d.netmask !== '0.0.0.0' ? d.netmask : '255.255.255.0',
                          gateway: d.gateway ?? '0.0.0.0',
                          permanent: true,
                        })
                      }
                    >
                      Name / IP…
                    </button>
                    <button type="button" data-testid="dcp-reset" disabled={busy !== null} onClick={() => setReset({ mac: d.mac, mode: 2 })}>
                      Reset…
                    </button>
                  </td>
                </tr>
              ))}
            </tbody>
          </table>
        </div>
      )}
      {edit !== null && (
        <form className="form-grid" onSubmit={(e) => void submit(e)} data-testid="dcp-edit-form">
          <div className="wide muted">
            Set <span className="mono">{edit.mac}</span>. A drive in data exchange with its controller (or with a
            servodesk session open) refuses a new name or address: close the session first.
          </div>
          <label>
            Station name
            <input data-testid="dcp-edit-name" className="mono" value={edit.name} onChange={(e) => setEdit({ ...edit, name: e.target.value })} spellCheck={false} />
          </label>
          <label>
            IP address
            <input data-testid="dcp-edit-ip" className="mono" value={edit.ip} onChange={(e) => setEdit({ ...edit, ip: e.target.value })} spellCheck={false} />
          </label>
          <label>
            Subnet mask
            <input data-testid="dcp-edit-netmask" className="mono" value={edit.netmask} onChange={(e) => setEdit({ ...edit, netmask: e.target.value })} spellCheck={false} />
          </label>
          <label title="0.0.0.0: no router">
            Gateway
            <input data-testid="dcp-edit-gateway" className="mono" value={edit.gateway} onChange={(e) => setEdit({ ...edit, gateway: e.target.value })} spellCheck={false} />
          </label>
          <label title="Unchecked: the device forgets the setting at its next power cycle">
            <span>
              <input type="checkbox" checked={edit.permanent} onChange={(e) => setEdit({ ...edit, permanent: e.target.checked })} /> keep over a power cycle
            </span>
          </label>
          {nameError && (
            <div className="inline-error wide" data-testid="dcp-edit-error">
              station name: {nameError}
            </div>
          )}
          <div className="form-actions">
            <button type="button" onClick={() => setEdit(null)}>
              Cancel
            </button>
            <button type="submit" className="primary" data-testid="dcp-edit-set" disabled={busy !== null || nameError !== null}>
              Set
            </button>
          </div>
        </form>
      )}
      {reset !== null && (
        <ConfirmDialog
          title={`Reset ${reset.mac} to factory`}
          confirmLabel={`Reset (option ${reset.mode})`}
          onConfirm={() => void doReset()}
          onCancel={() => setReset(null)}
          busy={busy !== null}
          testid="dcp-reset-dialog"
        >
          <p>
            The drive loses its station name and IP address (004 §20.4.5) and cannot be reached until they are set
            again. Both options write EEP-ROM.
          </p>
          <label>
            <input type="radio" checked={reset.mode === 2} onChange={() => setReset({ ...reset, mode: 2 })} /> option 2:
            communication parameters only
          </label>
          <br />
          <label>
            <input type="radio" data-testid="dcp-reset-mode-8" checked={reset.mode === 8} onChange={() => setReset({ ...reset, mode: 8 })} />{' '}
            option 8: also the drive's parameters (PA, PB, PC except PC11/PC12, PD, PE, PF, PL, PT, PN) and point tables
          </label>
        </ConfirmDialog>
      )}
    </section>
  );
}
