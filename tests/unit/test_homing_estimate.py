"""The homing run's estimated duration and default time-out (domain/homing.py), pure.

The numbers are the CTMM04x's own: 6099h:01 = 3000 pps and 6099h:02 = 10 pps by default (003
§4-4-8), 609Ah = 100 as a PMC842SR rate register (003 §5-3-1: Fclk / 8 / register with
multiplier 1 = 40960 pulses/s²), and its twin's switch layout (-EL at -222822, +EL at 484966,
ORG 170394 .. 222822, an index pulse every 131072 pulses).
"""

from __future__ import annotations

import math

import pytest

from servodesk.domain.homing import (
    CIA402_METHODS,
    DEFAULT_TIMEOUT_S,
    MAX_DEFAULT_TIMEOUT_S,
    MIN_TIMEOUT_S,
    HomingGeometry,
    default_timeout,
    estimate_duration,
    format_seconds,
    move_time,
    phase_from_statusword,
    register_acceleration,
    speed_multiplier,
    twin_geometry,
)
from servodesk.domain.profile_loader import ProfileCatalog

CTMM = ProfileCatalog().get("ctmm04x")
ACC = 32_768_000 / 8 / 100  # 609Ah = 100, multiplier 1 (003 §5-3-1).


def test_move_time_is_a_trapezoid_or_a_triangle() -> None:
    # 1000 at 100/s with 1000/s²: 0.1 s to speed and back, 10 s at speed in all.
    assert move_time(1000, 100, 1000) == pytest.approx(10.1)
    # Too short to reach the speed: a triangle, 2 sqrt(d/a).
    assert move_time(1, 100, 1000) == pytest.approx(2 * math.sqrt(1 / 1000))
    assert move_time(1000, 100, None) == pytest.approx(10.0)
    assert move_time(0, 100, 1000) == 0.0


def test_twin_geometry_of_the_ctmm04x() -> None:
    g = twin_geometry(CTMM.simulation, 131072, 131072)
    assert g is not None
    assert g.travel == 484966 + 222822
    assert g.index_spacing == 131072
    assert g.switch_width == 222822 - 170394
    # A twin on a 2^20 encoder: the same layout in revolutions.
    g8 = twin_geometry(CTMM.simulation, 1 << 20, 131072)
    assert g8 is not None and g8.travel == pytest.approx(8 * (484966 + 222822))


def test_ctmm_method_1_at_the_manuals_speeds_crawls_for_hours() -> None:
    # 003 §4-4-7 method 1: -EL at 6099h:01, decelerate, then positive at 6099h:02 up to the
    # EZ pulse. At 10 pps one revolution of 131072 pulses is 13107 s: the run the issue saw
    # "not finished after 240 s" was a quarter of an hour into a 3.7 h index search.
    g = twin_geometry(CTMM.simulation, 131072, 131072)
    assert g is not None
    est = estimate_duration(CIA402_METHODS[1], g, 3000, 10, ACC)
    assert est is not None
    names = [p.name for p in est.phases]
    assert names[0].startswith("search the limit switch")
    assert names[-1].startswith("search the index pulse")
    search, back, index = est.phases
    assert search.seconds == pytest.approx(707788 / 3000 + 3000 / ACC)
    assert back.distance == pytest.approx(3000**2 / (2 * ACC))  # Braking past -EL.
    assert back.speed_object == index.speed_object == "6099h:02"
    assert index.seconds == pytest.approx(131072 / 10 + 10 / ACC)
    assert est.seconds == pytest.approx(search.seconds + back.seconds + index.seconds)
    assert 3.6 * 3600 < est.seconds < 3.8 * 3600
    assert est.assumptions == ()
    # At 3000 pps for the zero search too, the whole run is about 5 minutes.
    fast = estimate_duration(CIA402_METHODS[1], g, 3000, 3000, ACC)
    assert fast is not None and fast.seconds < 300


def test_reversing_methods_search_twice_and_home_switches_are_crossed() -> None:
    g = HomingGeometry(10_000, "test", index_spacing=1000, switch_width=500)
    est7 = estimate_duration(CIA402_METHODS[7], g, 1000, 100, None)
    est3 = estimate_duration(CIA402_METHODS[3], g, 1000, 100, None)
    assert est7 is not None and est3 is not None
    assert est7.phases[0].distance == 20_000  # To the limit switch and back.
    assert est3.phases[0].distance == 10_000  # Methods 3-6 do not reverse.
    # Across the dog at the zero-search speed, then one revolution for the index.
    assert est7.phases[1].distance == 500 and est7.phases[2].distance == 1000
    assert est7.seconds == pytest.approx(20 + 5 + 10)
    assert est7.assumptions == (
        "the homing acceleration (609Ah) is not known here: ramps not counted",
    )


def test_what_is_not_known_is_said_not_guessed() -> None:
    g = HomingGeometry(10_000, "test")
    est = estimate_duration(CIA402_METHODS[7], g, 1000, 100, 1e6)
    assert est is not None
    assert any("width is not known" in a for a in est.assumptions)
    assert any("index search" in a for a in est.assumptions)
    assert [p.speed_object for p in est.phases] == ["6099h:01", "6099h:02"]  # Braking back.
    # No motion: nothing to wait for. A zero speed never ends: no estimate.
    assert estimate_duration(CIA402_METHODS[37], g, 0, 0, None) is not None
    assert estimate_duration(CIA402_METHODS[37], g, 0, 0, None).seconds == 0.0  # type: ignore[union-attr]
    assert estimate_duration(CIA402_METHODS[1], g, 1000, 0, None) is None


def test_default_timeout_is_twice_the_estimate_plus_a_margin_within_bounds() -> None:
    assert default_timeout(100) == pytest.approx(230)
    assert default_timeout(0) == MIN_TIMEOUT_S
    assert default_timeout(13_000) == MAX_DEFAULT_TIMEOUT_S
    assert default_timeout(None) == DEFAULT_TIMEOUT_S


def test_ctmm_rate_register_and_speed_multiplier() -> None:
    q = CTMM.quirk("speed_multiplier")
    table = q["table"]
    # 003 §5-3-1 table 5-3-1-2: 607Fh selects the multiplier.
    assert speed_multiplier(table, 8191) == 1
    assert speed_multiplier(table, 8192) == 2
    assert speed_multiplier(table, 409550) == 50
    assert speed_multiplier(table, 8_191_000) == 1000
    assert speed_multiplier(None, 8191) == 1
    assert register_acceleration(32_768_000, 100) == pytest.approx(40960)
    # The ramp time for a given speed change is the same in registers whatever the
    # multiplier, so the rate in pulses/s² scales with it.
    assert register_acceleration(32_768_000, 100, 50) == pytest.approx(50 * 40960)
    assert register_acceleration(32_768_000, 0) is None


@pytest.mark.parametrize(
    ("statusword", "phase"),
    [
        (0x0000, "in progress"),
        (0x0400, "interrupted or not started"),
        (0x1000, "attained, target not reached yet"),
        (0x1400, "attained"),
        (0x2000, "error, the axis still moves"),
        (0x2400, "error, the axis stands"),
    ],
)
def test_phase_from_statusword_bits_13_12_10(statusword: int, phase: str) -> None:
    assert phase_from_statusword(statusword | 0x0237) == phase


def test_format_seconds() -> None:
    assert format_seconds(2.5) == "2.5 s"
    assert format_seconds(42) == "42 s"
    assert format_seconds(200) == "3 min 20 s"
    assert format_seconds(13_400) == "3 h 43 min"
