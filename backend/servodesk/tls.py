"""HTTPS for a server reached over the network: the user's certificate, or one made here.

IEC 62443-4-2 CR 4.1 / CR 3.1 (confidentiality and integrity of information in transit) and
the newest drive web servers (SINAMICS V6: HTTPS by default) set the bar: a login, a session
cookie or an API token must not cross a plant network in clear text. So ``servodesk serve``
bound beyond loopback serves HTTPS (docs/security.md, "TLS"):

- ``--tls-cert FILE --tls-key FILE``: the user's certificate (PEM, the chain after the leaf)
  and its private key (PEM, unencrypted). Both are checked before the server starts.
- Otherwise a self-signed certificate made on the first start, with the ``cryptography``
  package, into ``<data_dir>/tls/`` (``servodesk.crt``, ``servodesk.key`` with mode 0600) and
  reused on later starts. Its subject alternative names are the machine's host name, the
  addresses the server is bound to (every local address for 0.0.0.0 / ::), ``localhost``,
  127.0.0.1 and ::1. A browser cannot know it and warns once: the SHA-256 fingerprint printed
  at start is what the user compares with the one the browser shows before accepting it. It
  is made again (and says so) when it has expired, expires within 30 days, or no longer
  names every address the server is bound to.

Loopback stays plain HTTP (only this machine can reach it; ``make demo`` needs no
certificate). Plain HTTP beyond loopback needs ``--insecure-http``.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import ipaddress
import os
import socket
import ssl
import struct
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from servodesk.errors import ServodeskError
from servodesk.files import MiB, read_bounded
from servodesk.hosts import ip_literal

IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address

#: A self-signed certificate is made for this long. Browsers' 398-day cap applies to publicly
#: trusted certificates only; one the user accepted by its fingerprint stays accepted until
#: it changes, so a long life spares the user the comparison.
VALIDITY = dt.timedelta(days=3650)
#: Made again when it expires within this.
RENEW_BEFORE = dt.timedelta(days=30)
#: Certificate and key files are read with this bound (files.read_bounded).
MAX_PEM = 1 * MiB


class TlsError(ServodeskError):
    """The certificate or key cannot be used (CLI: exit 2 with the message)."""


@dataclass(frozen=True)
class TlsFiles:
    cert: Path
    key: Path
    #: SHA-256 over the certificate's DER, as browsers show it: ``AB:CD:...``.
    fingerprint: str
    #: True: made here (self-signed); False: the user's.
    generated: bool
    #: What happened to a generated one: "made", "reused", "made again (<why>)".
    note: str = ""


def fingerprint(cert_pem: bytes) -> str:
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes

    cert = x509.load_pem_x509_certificate(cert_pem)
    return ":".join(f"{b:02X}" for b in cert.fingerprint(hashes.SHA256()))


def user_files(cert: str | Path, key: str | Path) -> TlsFiles:
    """The user's certificate and key, checked the way the server will load them."""
    cert_path, key_path = Path(cert), Path(key)
    pem = _read(cert_path, "certificate")
    _read(key_path, "key")
    try:
        fp = fingerprint(pem)
    except ValueError as exc:
        raise TlsError(
            f"{cert_path}: not a PEM certificate ({exc})",
            hint="give the certificate as PEM (-----BEGIN CERTIFICATE-----)",
        ) from None
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    try:
        context.load_cert_chain(cert_path, key_path)
    except ssl.SSLError as exc:
        raise TlsError(
            f"{key_path} is not the private key of {cert_path} or cannot be read "
            f"({exc.reason or exc})",
            hint="give the certificate's own unencrypted PEM key with --tls-key",
        ) from None
    return TlsFiles(cert_path, key_path, fp, generated=False)


def _read(path: Path, what: str) -> bytes:
    try:
        return read_bounded(path, MAX_PEM)
    except OSError as exc:
        raise TlsError(
            f"cannot read the {what} file {path}: {exc.strerror or exc}",
            hint=f"check the path given with --tls-{'cert' if what == 'certificate' else 'key'}",
        ) from None
    except ServodeskError as exc:
        raise TlsError(exc.message, hint=exc.hint) from None


# Self-signed --------------------------------------------------------------------------------


def self_signed(data_dir: Path, host: str) -> TlsFiles:
    """The self-signed certificate of ``data_dir`` for a server bound to ``host``: reused
    when it still fits, made (again) otherwise."""
    directory = Path(data_dir) / "tls"
    cert_path, key_path = directory / "servodesk.crt", directory / "servodesk.key"
    names, addresses = subject_names(host)
    why = _unfit(cert_path, key_path, names, addresses)
    if why is None:
        pem = cert_path.read_bytes()
        return TlsFiles(cert_path, key_path, fingerprint(pem), generated=True, note="reused")
    try:
        directory.mkdir(parents=True, exist_ok=True)
        cert_pem, key_pem = _make(names, addresses)
        # The key first, never readable by others (mode 0600 from its creation).
        _write_private(key_path, key_pem, 0o600)
        _write_private(cert_path, cert_pem, 0o644)
    except OSError as exc:
        raise TlsError(
            f"cannot write the TLS certificate into {directory}: {exc.strerror or exc}",
            hint="set SERVODESK_DATA_DIR to a directory you can write, give your own "
            "certificate with --tls-cert and --tls-key, or (on a network you trust) "
            "--insecure-http",
        ) from None
    note = "made" if why == "missing" else f"made again ({why})"
    return TlsFiles(cert_path, key_path, fingerprint(cert_pem), generated=True, note=note)


def subject_names(host: str) -> tuple[list[str], list[IPAddress]]:
    """DNS names and IP addresses the certificate of a server bound to ``host`` names."""
    names = ["localhost"]
    for name in (socket.gethostname(), socket.getfqdn()):
        name = name.strip().lower().rstrip(".")
        if name and ip_literal(name) is None and name not in names:
            names.append(name)
    addresses: list[IPAddress] = [ipaddress.ip_address("127.0.0.1"), ipaddress.ip_address("::1")]
    bound = ip_literal(host.strip())
    if bound is None:
        name = host.strip().lower().rstrip(".")
        if name and name not in names:
            names.append(name)
        found = _resolve(name)
    elif bound.is_unspecified:
        found = local_addresses()
    else:
        found = [bound]
    for a in found:
        if a not in addresses:
            addresses.append(a)
    return names, addresses


def local_addresses() -> list[IPAddress]:
    """This machine's addresses (what 0.0.0.0 / :: listens on), link-local ones left out (a
    browser cannot use them in a URL without a zone)."""
    found: list[IPAddress] = []

    def add(text: str) -> None:
        with contextlib.suppress(ValueError):
            a = ipaddress.ip_address(text.split("%", 1)[0])
            if not a.is_link_local and not a.is_unspecified and a not in found:
                found.append(a)

    if sys.platform.startswith("linux"):
        import fcntl

        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _, nic in socket.if_nameindex():
                with contextlib.suppress(OSError):  # SIOCGIFADDR: the interface's IPv4.
                    packed = fcntl.ioctl(s.fileno(), 0x8915, struct.pack("256s", nic[:15].encode()))
                    add(socket.inet_ntoa(packed[20:24]))
        with contextlib.suppress(OSError), open("/proc/net/if_inet6") as f:
            for line in f:
                raw = line.split()[0]
                add(":".join(raw[i : i + 4] for i in range(0, 32, 4)))
    for a in _resolve(socket.gethostname()):
        add(str(a))
    return found


def _resolve(name: str) -> list[IPAddress]:
    out: list[IPAddress] = []
    with contextlib.suppress(OSError, UnicodeError):
        for info in socket.getaddrinfo(name, None):
            with contextlib.suppress(ValueError):
                a = ipaddress.ip_address(str(info[4][0]).split("%", 1)[0])
                if a not in out:
                    out.append(a)
    return out


def _unfit(cert: Path, key: Path, names: list[str], addresses: list[IPAddress]) -> str | None:
    """Why the certificate in ``cert`` cannot be reused (None: it can)."""
    from cryptography import x509

    if not cert.is_file() or not key.is_file():
        return "missing"
    try:
        c = x509.load_pem_x509_certificate(cert.read_bytes())
        context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        context.load_cert_chain(cert, key)
        san = c.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except (OSError, ValueError, ssl.SSLError, x509.ExtensionNotFound):
        return "the old one could not be read"
    if c.not_valid_after_utc - RENEW_BEFORE < dt.datetime.now(dt.UTC):
        return "the old one expires on " + c.not_valid_after_utc.date().isoformat()
    has_names = {n.lower() for n in san.get_values_for_type(x509.DNSName)}
    has_addresses = set(san.get_values_for_type(x509.IPAddress))
    missing = [n for n in names if n not in has_names] + [
        str(a) for a in addresses if a not in has_addresses
    ]
    if missing:
        return "the old one does not name " + ", ".join(missing)
    return None


def _make(names: list[str], addresses: list[IPAddress]) -> tuple[bytes, bytes]:
    """A self-signed server certificate (ECDSA P-256, SHA-256) and its key, both PEM."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name(
        [
            x509.NameAttribute(NameOID.COMMON_NAME, f"servodesk on {names[-1]}"[:64]),
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "servodesk (self-signed)"),
        ]
    )
    now = dt.datetime.now(dt.UTC)
    san: list[x509.GeneralName] = [x509.DNSName(n) for n in names]
    san += [x509.IPAddress(a) for a in addresses]
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + VALIDITY)
        .add_extension(x509.SubjectAlternativeName(san), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=False,
                crl_sign=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH]), critical=False)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    key_pem = key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )
    return cert.public_bytes(serialization.Encoding.PEM), key_pem


def _write_private(path: Path, data: bytes, mode: int) -> None:
    """Write ``data`` to a new temporary file created with ``mode``, then rename it over
    ``path``: never half-written, and a key is never readable by others, not even briefly."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
