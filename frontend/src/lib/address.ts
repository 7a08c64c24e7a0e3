/**
 * Object dictionary addresses as a person types them (CiA 301 §7.4.1: 16-bit index, 8-bit
 * subindex), parsed the same way as the backend's ObjectAddress.parse so the UI can refuse
 * a typo before it goes to the server.
 *
 * Accepted: `0x6040`, `0x6040:00`, `6040h.1`, `6040`, and a PROFIdrive parameter number
 * `P24640` / `P24640.1` / `P24640[1]` (the CiA index in decimal, LECSN manual §20.2). A bare
 * index is hex (the way manuals print it); the subindex after `:` or `.` is hex too, a PNU's
 * subindex is decimal.
 */

export interface ObjectAddress {
  index: number;
  subindex: number;
}

export type AddressParse = { ok: true; address: ObjectAddress } | { ok: false; message: string; hint: string };

const ADDR = /^\s*(?:0x)?([0-9a-f]{1,4})h?\s*(?:[:.]\s*(?:0x)?([0-9a-f]{1,2})h?)?\s*$/i;
const PNU = /^\s*P(\d{1,5})(?:\s*[:.[]\s*(\d{1,3})\]?)?\s*$/i;
const HINT = 'write it as 0x6040, 0x6040:00, 6040h.0 or (PROFINET) P24640';

export function parseAddress(text: string): AddressParse {
  const pnu = PNU.exec(text);
  if (pnu) {
    const index = Number.parseInt(pnu[1] ?? '', 10);
    const subindex = pnu[2] === undefined ? 0 : Number.parseInt(pnu[2], 10);
    if (index > 0xffff) return { ok: false, message: `parameter number ${index} is above 65535`, hint: HINT };
    if (subindex > 0xff) return { ok: false, message: `subindex ${subindex} is above 255`, hint: HINT };
    return { ok: true, address: { index, subindex } };
  }
  const m = ADDR.exec(text);
  if (!m) {
    const shown = text.trim() === '' ? 'an empty address' : `"${text.trim()}"`;
    return { ok: false, message: `${shown} is not an object address`, hint: HINT };
  }
  const index = Number.parseInt(m[1] ?? '', 16);
  const subindex = m[2] === undefined ? 0 : Number.parseInt(m[2], 16);
  return { ok: true, address: { index, subindex } };
}

/** The canonical spelling used by the API and the backend: `0x6040:00`. */
export function formatAddress(a: ObjectAddress): string {
  return `0x${a.index.toString(16).toUpperCase().padStart(4, '0')}:${a.subindex
    .toString(16)
    .toUpperCase()
    .padStart(2, '0')}`;
}
