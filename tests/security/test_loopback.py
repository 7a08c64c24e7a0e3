"""Defect 6: only literal loopback addresses and "localhost" count as loopback (RFC 6761
§6.3 reserves the name; 127.0.0.0/8 and ::1 are loopback by RFC 1122 §3.2.1.3, RFC 4291
§2.5.3). A name that merely starts with "127." is some other machine."""

from __future__ import annotations

import pytest

from servodesk.settings import Settings


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.2", "127.255.1.9", "::1", "localhost"])
def test_loopback_addresses(host: str) -> None:
    assert Settings(host=host).is_loopback
    from servodesk.hosts import is_loopback

    assert is_loopback(host)


@pytest.mark.parametrize(
    "host",
    ["127.attacker.example", "127.0.0.1.nip.io", "0.0.0.0", "::", "192.168.1.5", "localhost.evil"],
)
def test_names_that_only_look_like_loopback(host: str) -> None:
    assert not Settings(host=host).is_loopback
    from servodesk.hosts import is_loopback

    assert not is_loopback(host)


def test_viewer_uses_the_same_rule() -> None:
    from servodesk.services import viewer

    assert not viewer.is_loopback("127.attacker.example")
