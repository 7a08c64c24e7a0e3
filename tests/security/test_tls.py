"""HTTPS beyond loopback (servodesk/tls.py, docs/security.md "TLS"): a real ``servodesk
serve --host 0.0.0.0`` answers HTTPS with the self-signed certificate it made on its first
start, whose fingerprint it printed, and reuses it; plain HTTP beyond loopback only with
--insecure-http; a certificate or key that cannot be used is exit 2 with a message."""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import socket
import ssl
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from cryptography import x509

from servodesk import tls
from servodesk.cli import main
from tests.live import free_port

FINGERPRINT = re.compile(r"SHA-256 fingerprint ((?:[0-9A-F]{2}:){31}[0-9A-F]{2})")


def _env(data: Path) -> dict[str, str]:
    return {
        **os.environ,
        "SERVODESK_DATA_DIR": str(data),
        "SERVODESK_VIEWER_PORT": "0",
        "SERVODESK_LOG_LEVEL": "warning",
    }


def _admin(data: Path) -> None:
    """An account, as a server beyond loopback needs one (docs/security.md, First start)."""
    if (
        "users"
        not in subprocess.run(
            [sys.executable, "-m", "servodesk", "--help"], capture_output=True, text=True
        ).stdout
    ):
        return
    subprocess.run(
        [
            sys.executable,
            "-m",
            "servodesk",
            "users",
            "add",
            "admin",
            "--role",
            "administrator",
            "--password-stdin",
        ],
        input="correct horse battery\n",
        env=_env(data),
        check=True,
        capture_output=True,
        text=True,
    )


@contextlib.contextmanager
def _serve(data: Path, *args: str) -> Iterator[tuple[int, str]]:
    """``servodesk serve --host 0.0.0.0 ...`` on a free port; (port, what it printed) once it
    accepts connections."""
    port = free_port()
    log = data / f"serve-{port}.log"
    with open(log, "w") as out:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "servodesk",
                "serve",
                "--host",
                "0.0.0.0",
                "--port",
                str(port),
                *args,
            ],
            env=_env(data),
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    try:
        deadline = time.monotonic() + 40
        while True:
            if proc.poll() is not None:
                raise AssertionError(f"serve exited with {proc.returncode}:\n{log.read_text()}")
            with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 1):
                break
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.2)
        yield port, log.read_text()
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _peer_certificate(port: int) -> bytes:
    context = ssl.create_default_context()
    context.check_hostname = False
    context.verify_mode = ssl.CERT_NONE  # Self-signed: the fingerprint is what is compared.
    with (
        socket.create_connection(("127.0.0.1", port), 5) as raw,
        context.wrap_socket(raw, server_hostname="localhost") as s,
    ):
        der = s.getpeercert(binary_form=True)
    assert der
    return der


def _colons(digest: bytes) -> str:
    return ":".join(f"{b:02X}" for b in digest)


def test_beyond_loopback_serves_https_with_the_printed_certificate(tmp_path: Path) -> None:
    _admin(tmp_path)
    with _serve(tmp_path) as (port, printed):
        found = FINGERPRINT.search(printed)
        assert found, printed
        assert f"https://127.0.0.1:{port}/" in printed
        der = _peer_certificate(port)
        assert _colons(hashlib.sha256(der).digest()) == found.group(1)
        # The server answers over HTTPS (401 where a login is needed is an answer too).
        r = httpx.get(f"https://127.0.0.1:{port}/api/v1/health", verify=False, timeout=5)
        assert r.status_code in (200, 401), r.text
        # Plain HTTP on the same port gets no page (at most uvicorn's bare 400).
        try:
            plain: int | None = httpx.get(
                f"http://127.0.0.1:{port}/api/v1/health", timeout=5
            ).status_code
        except httpx.HTTPError:
            plain = None
        assert plain in (None, 400)
        # The names it is made for; no HSTS for a loopback name (make demo is plain HTTP).
        names = {
            n.value
            for n in x509.load_der_x509_certificate(der)
            .extensions.get_extension_for_class(x509.SubjectAlternativeName)
            .value
            if isinstance(n, x509.DNSName)
        }
        assert "localhost" in names and socket.gethostname().lower() in names
        r = httpx.get(f"https://localhost:{port}/api/v1/health", verify=False, timeout=5)
        assert "strict-transport-security" not in r.headers
    cert, key = tmp_path / "tls" / "servodesk.crt", tmp_path / "tls" / "servodesk.key"
    assert stat.S_IMODE(key.stat().st_mode) == 0o600
    san = (
        x509.load_pem_x509_certificate(cert.read_bytes())
        .extensions.get_extension_for_class(x509.SubjectAlternativeName)
        .value
    )
    addresses = {str(a) for a in san.get_values_for_type(x509.IPAddress)}
    assert {"127.0.0.1", "::1"} <= addresses
    # The next start reuses it: the same fingerprint, nothing for the user to compare again.
    with _serve(tmp_path) as (port, printed_again):
        assert "reused" in printed_again
        again = FINGERPRINT.search(printed_again)
        assert again and again.group(1) == found.group(1)
        assert _colons(hashlib.sha256(_peer_certificate(port)).digest()) == found.group(1)


def test_insecure_http_is_plain_and_warns(tmp_path: Path) -> None:
    _admin(tmp_path)
    with _serve(tmp_path, "--insecure-http") as (port, printed):
        assert "WARNING: plain HTTP" in printed
        r = httpx.get(f"http://127.0.0.1:{port}/api/v1/health", timeout=5)
        assert r.status_code in (200, 401)
    assert not (tmp_path / "tls").exists()


def test_the_users_certificate_is_served(tmp_path: Path) -> None:
    cert_pem, key_pem = tls._make(["plant-pc.example"], [])
    cert, key = tmp_path / "c.pem", tmp_path / "k.pem"
    cert.write_bytes(cert_pem)
    key.write_bytes(key_pem)
    _admin(tmp_path)
    with _serve(tmp_path, "--tls-cert", str(cert), "--tls-key", str(key)) as (port, printed):
        assert tls.fingerprint(cert_pem) in printed
        assert _peer_certificate(port) == x509.load_pem_x509_certificate(cert_pem).public_bytes(
            __import__(
                "cryptography.hazmat.primitives.serialization", fromlist=["Encoding"]
            ).Encoding.DER
        )
    assert not (tmp_path / "tls").exists()  # Nothing generated.


def _refused(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["serve", *args]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def test_bad_certificate_or_key_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cert_pem, key_pem = tls._make(["a.example"], [])
    _, other_key = tls._make(["b.example"], [])
    cert, key, wrong, junk = (tmp_path / n for n in ("c.pem", "k.pem", "w.pem", "j.pem"))
    cert.write_bytes(cert_pem)
    key.write_bytes(key_pem)
    wrong.write_bytes(other_key)
    junk.write_text("not a certificate\n")
    assert "not a PEM certificate" in _refused(
        ["--tls-cert", str(junk), "--tls-key", str(key)], capsys
    )
    assert "not the private key" in _refused(
        ["--tls-cert", str(cert), "--tls-key", str(wrong)], capsys
    )
    assert "not the private key" in _refused(
        ["--tls-cert", str(cert), "--tls-key", str(junk)], capsys
    )
    assert "cannot read the certificate" in _refused(
        ["--tls-cert", str(tmp_path / "none.pem"), "--tls-key", str(key)], capsys
    )
    assert "go together" in _refused(["--tls-cert", str(cert)], capsys)
    assert "contradict" in _refused(
        ["--tls-cert", str(cert), "--tls-key", str(key), "--insecure-http"], capsys
    )


def test_no_plain_http_beyond_loopback_when_no_certificate_can_be_made(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The data directory cannot hold the certificate: exit 2, naming the ways out, rather
    than falling back to plain HTTP."""
    _admin(tmp_path)
    (tmp_path / "tls").write_text("a file where the directory would be")
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path))
    err = _refused(["--host", "0.0.0.0", "--port", str(free_port())], capsys)
    assert "cannot write the TLS certificate" in err and "--insecure-http" in err


def test_a_certificate_that_no_longer_names_the_bound_address_is_made_again(
    tmp_path: Path,
) -> None:
    first = tls.self_signed(tmp_path, "127.0.0.1")
    assert first.note == "made"
    assert tls.self_signed(tmp_path, "127.0.0.1").fingerprint == first.fingerprint
    other = tls.self_signed(tmp_path, "192.0.2.99")
    assert other.note.startswith("made again") and "192.0.2.99" in other.note
    assert other.fingerprint != first.fingerprint


def test_hsts_by_host_name_only(tmp_path: Path) -> None:
    """Under TLS a request by host name gets Strict-Transport-Security; one by IP address
    (RFC 6797 §8.1.1) or a loopback name does not (HSTS would hold for every port of the
    name, make demo's plain HTTP on localhost included)."""
    from fastapi.testclient import TestClient

    from servodesk.api.app import create_app
    from servodesk.settings import Settings

    files = tls.self_signed(tmp_path, "127.0.0.1")
    app = create_app(
        Settings(
            data_dir=tmp_path,
            tls_cert=files.cert,
            tls_key=files.key,
            allowed_hosts="plant-pc.example",
        )
    )
    with TestClient(app) as client:
        for host, expected in (
            ("plant-pc.example", True),
            ("127.0.0.1:8000", False),
            ("localhost:8000", False),
        ):
            r = client.get("/api/v1/health", headers={"Host": host})
            assert ("strict-transport-security" in r.headers) is expected, (host, r.headers)
