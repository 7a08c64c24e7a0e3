"""A homing run's estimate, time-out and end state, on the motion service and simulated drives.

The issue: a CTMM04x homing run with method 1 at the profile's (the manual's) speeds crawled at
10 pps after the limit switch with no progress, no estimate and no time-out; the dead-man
stopped it and the panel stayed on "running". On the CTMM04x a cancelled run leaves statusword
bits 13/12/10 all 0 (003 §4-4-7), which reads as "in progress": only the motion's end can say
that the run is over, so the run's last ``homing`` message carries it.

The twin of the CTMM04x (method 1: -EL at -1.7 rev of 131072 pulses, searched at 3000 pps)
is still on its way to the switch after a few seconds, long enough for a dead-man stop, a
loss of control or a short time-out.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

import pytest

from servodesk.services import homing
from tests.homing.service import Rig, rig

CTMM = "ctmm04x"


async def _final_homing(r: Rig, timeout: float = 2.0) -> dict[str, Any]:
    """The homing message that ended the run: it follows the motion's end (the dead-man's
    thread ends the motion first, services/deadman.py), and state polls may follow it."""
    end = asyncio.get_running_loop().time() + timeout
    while True:
        done = [m for m in r.of_type("homing") if (m.get("run") or {}).get("outcome") != "running"]
        if done or asyncio.get_running_loop().time() > end:
            assert done, "no homing message ended the run"
            return done[0]
        await asyncio.sleep(0.02)


def _last_homing(r: Rig) -> dict[str, Any]:
    msgs = r.of_type("homing")
    assert msgs, "no homing message was published"
    return msgs[-1]


async def _after_end(r: Rig, seconds: float) -> list[dict[str, Any]]:
    """The homing messages published ``seconds`` after the motion ended (state polls go on)."""
    n = len(r.messages)
    await asyncio.sleep(seconds)
    return [m for m in r.messages[n:] if m.get("type") == "homing"]


async def test_the_start_answers_the_estimate_and_the_time_out_at_the_manuals_speeds(
    channel: str,
) -> None:
    async with rig(channel, CTMM) as r:
        await r.enable()
        r.start_heartbeats()
        # No speeds given: the drive's, 6099h:01 = 3000 pps and 6099h:02 = 10 pps (003 §4-4-8).
        st = await r.motion.home(r.sid, "A", 1)
        run = st["run"]
        assert run["active"] and run["outcome"] == "running" and run["watched"]
        assert (run["speed_switch"], run["speed_zero"]) == (3000.0, 10.0)
        # 609Ah = 100 as a PMC842SR rate register (003 §5-3-1): 32.768 MHz / 8 / 100.
        assert run["acceleration"] == 40960.0
        assert run["basis"].endswith("the simulated twin's limit switches")
        # Up to one revolution (131072 pulses) at 10 pps for the index pulse: hours.
        assert 3.6 * 3600 < run["estimate_s"] < 3.8 * 3600
        index = run["estimate"]["phases"][-1]
        assert index["speed_object"] == "6099h:02" and index["seconds"] > 13000
        # The default time-out is bounded at an hour and says it is shorter than the estimate.
        assert run["timeout_s"] == 3600 and run["timeout_source"] == "estimate"
        assert any("6099h:02" in w for w in run["warnings"])
        assert any("shorter than the estimate" in w for w in run["warnings"])
        m = r.motion.status(r.sid)
        assert m["kind"] == "homing" and "time-out 1 h 0 min" in m["message"]
        # Progress: the elapsed time grows in the homing messages and the status.
        await asyncio.sleep(0.6)
        later = await homing.status(r.session)
        assert later["state"] == "running" and later["run"]["elapsed_s"] >= 0.5
        assert later["run"]["phase"] == "in progress"
        assert "of up to 3 h" in later["message"]
        assert _last_homing(r)["run"]["elapsed_s"] > 0.3
        await r.motion.halt(r.sid, "A")


async def test_a_time_out_halts_the_run_and_says_so(channel: str) -> None:
    async with rig(channel, CTMM) as r:
        await r.enable()
        r.start_heartbeats()
        t0 = time.monotonic()
        st = await r.motion.home(r.sid, "A", 1, timeout_s=1.0)
        assert st["run"]["timeout_s"] == 1.0 and st["run"]["timeout_source"] == "user"
        await asyncio.sleep(0.5)
        assert r.drive.velocity < -1000  # On its way to -EL at 3000 pps.
        end = await r.wait_motion_end(3.0)
        took = time.monotonic() - t0
        assert end["state"] == "timeout", end
        assert "timed out after 1 s" in end["message"], end
        assert 1.0 <= took < 2.5, took  # The monitor samples every 50 ms; a busy machine.
        # Halted: the axis stands (the CTMM04x has no quick stop, 003 §4-4-1; the halt stops it).
        assert await r.wait_until(lambda: abs(r.drive.velocity) <= 1, 1.0)
        last = _last_homing(r)
        assert last["run"]["outcome"] == "timeout" and not last["run"]["active"]
        assert "timed out after 1 s" in last["message"]
        assert last["state"] != "running"
        st = await homing.status(r.session)
        assert st["run"]["outcome"] == "timeout" and st["state"] != "running"
        assert 1.0 <= st["run"]["elapsed_s"] < 2.5


async def test_a_dead_man_stop_is_the_runs_published_end(channel: str) -> None:
    async with rig(channel, CTMM, deadman_s=0.25) as r:
        await r.enable()
        r.start_heartbeats()
        await r.motion.home(r.sid, "A", 1)
        await asyncio.sleep(0.5)
        assert r.drive.velocity < -1000
        r.stop_heartbeats()
        end = await r.wait_motion_end(2.0)
        assert end["state"] == "deadman", end
        last = await _final_homing(r)
        assert last["run"]["outcome"] == "deadman" and not last["run"]["active"], last
        assert "heartbeat" in last["message"]
        # The halt cancelled the run: the CTMM04x clears bits 13/12/10 (003 §4-4-7), which
        # reads as "in progress", yet nothing says "running" any more.
        later = await _after_end(r, 0.6)
        assert r.drive.statusword & 0x3400 == 0
        assert all(m["state"] != "running" for m in later), later
        assert all(not m["run"]["active"] for m in later), later
        st = await homing.status(r.session)
        assert st["state"] == "idle" and st["run"]["outcome"] == "deadman"
        assert "heartbeat" in st["message"]


async def test_losing_control_is_the_runs_published_end(channel: str) -> None:
    async with rig(channel, CTMM) as r:
        await r.enable()
        r.start_heartbeats()
        await r.motion.home(r.sid, "A", 1)
        await asyncio.sleep(0.3)
        r.control.lose(r.sid, "B", "control taken over by 'B'")
        end = await r.wait_motion_end(2.0)
        assert end["state"] in ("halted", "deadman"), end
        last = _last_homing(r)
        assert last["run"]["outcome"] == "control_lost", last
        assert "taken over" in last["message"]


async def test_a_run_that_attains_ends_attained_within_its_estimate(channel: str) -> None:
    # HIWIN E method 17 at 1 rev/s: to the negative limit switch 1.7 rev away and back off it.
    rev = 8_388_608
    async with rig(channel, "hiwin-e") as r:
        await r.enable()
        r.start_heartbeats()
        st = await r.motion.home(
            r.sid, "A", 17, speed_switch=rev, speed_zero=rev // 6, acceleration=10 * rev
        )
        est = st["run"]["estimate_s"]
        # The twin's travel: 5.4 rev from limit switch to limit switch.
        assert abs(st["run"]["travel"] - 5.4 * rev) < 2
        assert 5.0 < est < 7.0, est
        # Twice the estimate plus 30 s, but at least a minute.
        assert st["run"]["timeout_s"] == pytest.approx(max(60.0, 2 * est + 30))
        end = await r.wait_motion_end(10.0)
        assert end["state"] == "done", end

        # The run's end is published as attained: the last message's run (what the panel
        # shows) is over and attained. Its statusword bits are the last poll's and may read
        # "idle" (the mode given back) or miss the attained window between two polls.
        def attained() -> bool:
            run = r.of_type("homing")[-1]["run"]
            return run["outcome"] == "attained" and not run["active"]

        assert await r.wait_until(attained, 2.0), _last_homing(r)
        last = _last_homing(r)
        assert last["run"]["elapsed_s"] < est


async def test_the_plan_route_shows_the_estimate_and_time_out_before_the_start(
    channel: str, tmp_path: Any
) -> None:
    # GET /homing/plan reads the drive's speeds and answers what a run would get; nothing is
    # written and no control is needed, so the panel can show it before the start.
    import httpx

    from servodesk.api.app import create_app
    from servodesk.settings import Settings

    app = create_app(
        Settings(sim=True, sim_channel=channel, sim_profiles=CTMM, data_dir=tmp_path, viewer_port=0)
    )
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
            sessions = (await c.get("/api/v1/sessions")).json()
            sid = next(s["id"] for s in sessions if s["profile_id"] == CTMM)
            r = await c.get(f"/api/v1/sessions/{sid}/homing/plan", params={"method": 1})
            assert r.status_code == 200, r.text
            p = r.json()
            assert 3.6 * 3600 < p["estimate_s"] < 3.8 * 3600
            assert p["timeout_s"] == 3600 and p["timeout_source"] == "estimate"
            r = await c.get(
                f"/api/v1/sessions/{sid}/homing/plan",
                params={"method": 1, "speed_zero": 3000, "max_travel": 300000, "timeout_s": 90},
            )
            p = r.json()
            assert p["basis"] == "travel 300000 from your maximum travel"
            assert p["estimate_s"] < 200 and p["timeout_s"] == 90 and p["timeout_source"] == "user"
            r = await c.get(f"/api/v1/sessions/{sid}/homing/plan", params={"method": 3})
            assert r.status_code == 400 and "not documented" in r.json()["message"]
            r = await c.get(
                f"/api/v1/sessions/{sid}/homing/plan", params={"method": 1, "timeout_s": 0}
            )
            assert r.status_code == 422


async def test_a_run_without_servo_on_is_not_a_motion_and_ends_on_the_statusword(
    channel: str,
) -> None:
    # HIWIN 37 (quirk homing_without_enable, 000 §3.2.4 table 3.2.4.4): the current position
    # becomes home with the servo off. Nothing moves, so no motion and no dead-man; the run
    # still ends, on the statusword, and says so.
    async with rig(channel, "hiwin-e") as r:
        r.control.holder = "A"
        st = await r.motion.home(r.sid, "A", 37, offset=500)
        assert st["run"]["watched"] is False and st["run"]["estimate_s"] == 0.0
        assert r.motion.status(r.sid)["kind"] is None
        assert await r.wait_until(lambda: bool(r.of_type("homing")), 2.0)
        assert await r.wait_until(lambda: not _last_homing(r)["run"]["active"], 2.0)
        last = _last_homing(r)
        assert last["run"]["outcome"] == "attained" and "attained" in last["message"], last
