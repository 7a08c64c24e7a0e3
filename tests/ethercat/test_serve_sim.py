"""``serve --sim`` with ``SERVODESK_SIM_ETHERCAT=1``: the HIWIN twin on a simulated EtherCAT
line behind a veth pair, opened and moved through the EtherCAT link (pysoem); without the
right to make the pair, it stays a CANopen node and its note says why (docs/ethercat.md)."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path

from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.ethercat.nobody import as_nobody, nobody_dir
from tests.operation.support import headers, take_and_enable, wait_motion, wait_until

A = headers("A")


def _app(channel: str, data: Path, **kw: object) -> Iterator[tuple[TestClient, object]]:
    s = Settings(
        sim=True,
        sim_channel=channel,
        sim_profiles="cia402-generic,hiwin-e",
        data_dir=data,
        deadman_ms=1000,
        viewer_port=0,
        **kw,  # type: ignore[arg-type]
    )
    app = create_app(s)
    with TestClient(app) as client:
        yield client, app.state.servodesk.sim


def test_the_hiwin_twin_is_opened_and_moved_over_ethercat(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    gen = _app(channel, tmp_path, sim_ethercat=True)
    client, sim = next(gen)
    try:
        assert sim.veth is not None  # type: ignore[attr-defined]
        master = sim.veth.master  # type: ignore[attr-defined]
        info = client.get("/api/v1/sessions/hiwin-e-1").json()
        assert (info["fieldbus"], info["link"], info["interface"], info["channel"]) == (
            "ethercat",
            "ethercat",
            "ethercat",
            master,
        )
        assert info["note"] is None and info["nmt_state"] == "preop"
        assert info["identity"]["vendor_id"] == 0xAAAA
        drive = next(d for d in sim.drives if d.profile.id == "hiwin-e")  # type: ignore[attr-defined]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, "hiwin-e-1", "A", ws)
            try:
                # The drive's own watchdog is reported: the ESC's process data watchdog
                # (the twin's default, 2498 x 1000 divider ticks), read by SOEM.
                assert wait_until(
                    lambda: (
                        "SyncManager watchdog 100 ms"
                        in str(
                            client.get("/api/v1/sessions/hiwin-e-1/control").json()["protection"][
                                "drive_watchdog"
                            ]
                        )
                    ),
                    5.0,
                    step=0.1,
                )
                start = drive.position
                r = client.post(
                    "/api/v1/sessions/hiwin-e-1/motion/move",
                    json={"mode": "relative", "target": 20_000, "velocity": 100_000},
                    headers=A,
                )
                assert r.status_code == 200, r.text
                done = wait_motion(client, "hiwin-e-1", timeout=10)
                assert done["state"] == "reached", done
                assert abs(drive.position - start - 20_000) <= 100
            finally:
                beats.stop()
    finally:
        gen.close()
    # The pair goes with the server.
    assert not os.path.exists(f"/sys/class/net/{master}")


def test_without_the_right_to_make_the_pair_the_twin_stays_on_canopen() -> None:
    # Run for real as an unprivileged user: `ip link add` is refused.
    code = (
        "import json; from fastapi.testclient import TestClient; "
        "from servodesk.api.app import create_app; from servodesk.settings import Settings; "
        "s = Settings(sim=True, sim_channel='nobody-ecat', sim_profiles='hiwin-e', "
        "sim_ethercat=True, viewer_port=0); app = create_app(s)\n"
        "with TestClient(app) as c: print(json.dumps(c.get('/api/v1/sessions').json()))"
    )
    with nobody_dir() as d:
        done = as_nobody("-c", code, cwd=d)
    assert done.returncode == 0, done.stderr
    (hiwin,) = json.loads(done.stdout.strip().splitlines()[-1])
    assert hiwin["link"] == "canopen" and hiwin["id"] == "hiwin-e-1"
    assert "SERVODESK_SIM_ETHERCAT" in hiwin["note"] and "not permitted" in hiwin["note"]
    assert "the EtherCAT twin stays on CANopen" in done.stderr
