"""The veth pair helper: both ends exist and are up, names fit IFNAMSIZ, deletion removes
them, and a name that cannot be made or a refusal is a clear error."""

from __future__ import annotations

from pathlib import Path

import pytest

from servodesk.errors import ValidationError
from servodesk.sim.veth import IFNAME_MAX, create_veth
from tests.ethercat.nobody import as_nobody


def _up(name: str) -> bool:
    flags = int((Path("/sys/class/net") / name / "flags").read_text(), 16)
    return bool(flags & 0x1)  # IFF_UP


def test_create_and_delete_a_pair() -> None:
    pair = create_veth("sdv")
    try:
        assert pair.master != pair.slave
        for name in (pair.master, pair.slave):
            assert len(name) <= IFNAME_MAX
            assert _up(name), name
        # The two ends are each other's peer.
        peer = (Path("/sys/class/net") / pair.master / "iflink").read_text().strip()
        assert peer == (Path("/sys/class/net") / pair.slave / "ifindex").read_text().strip()
        again = create_veth("sdv")
        again.delete()
        assert again.master != pair.master
    finally:
        pair.delete()
    assert not (Path("/sys/class/net") / pair.master).exists()
    assert not (Path("/sys/class/net") / pair.slave).exists()
    pair.delete()  # Gone already: fine.


def test_bad_prefix_and_a_refusal_are_clear_errors() -> None:
    with pytest.raises(ValidationError, match="longer than 15"):
        create_veth("averylongprefix")
    with pytest.raises(ValidationError, match="not alphanumeric"):
        create_veth("a-b")
    # The real refusal: the same call as an unprivileged user (no CAP_NET_ADMIN).
    code = (
        "from servodesk.sim.veth import create_veth\n"
        "try:\n"
        "    create_veth('sdv')\n"
        "except Exception as e:\n"
        "    print(type(e).__name__, '|', e.message, '|', e.hint)\n"
    )
    done = as_nobody("-c", code)
    assert "Traceback" not in done.stderr, done.stderr
    kind, message, hint = (part.strip() for part in done.stdout.split("|"))
    assert kind == "LinkError" and "not permitted" in message, done.stdout
    assert "CAP_NET_ADMIN" in hint
