"""``servodesk pdo show | apply | templates`` in-process against a simulated drive on a bus."""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from servodesk.cli import main
from servodesk.sim.bus import SimulatedBus

_n = itertools.count()


@pytest.fixture(scope="module")
def sim() -> Iterator[tuple[SimulatedBus, list[str]]]:
    channel = f"cli-pdo-{os.getpid()}-{next(_n)}"
    bus = SimulatedBus.start([("cia402-generic", 3), ("hiwin-e", 4)], channel=channel)
    try:
        yield bus, ["--interface", "virtual", "--channel", channel, "--timeout", "0.5"]
    finally:
        bus.stop()


@pytest.fixture(autouse=True)
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(d))
    return d


def test_show_apply_dry_run_and_apply(
    sim: tuple[SimulatedBus, list[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bus, opts = sim
    node = [*opts, "--node-id", "3"]
    assert main(["pdo", "show", *node, "--json"]) == 0
    view = json.loads(capsys.readouterr().out)
    assert view["kind"] == "canopen" and len(view["pdos"]) == 8

    layout = tmp_path / "layout.json"
    layout.write_text(
        json.dumps({"pdos": [{"direction": "tx", "number": 4, "entries": ["0x6064:00"]}]})
    )
    assert main(["pdo", "apply", str(layout), *node, "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "0x1A03:01 <- 0x60640020" in text and "dry run" in text
    assert bus.drives[0].read(0x1A03, 1) != 0x60640020  # Nothing written.

    assert main(["pdo", "apply", str(layout), *node, "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["ok"] and rep["verified"]
    assert bus.drives[0].read(0x1A03, 0) == 1 and bus.drives[0].read(0x1A03, 1) == 0x60640020

    # The export is a layout that applies back unchanged (nothing to write).
    assert main(["pdo", "show", *node, "--export", "json"]) == 0
    exported = tmp_path / "exported.json"
    exported.write_text(capsys.readouterr().out)
    assert main(["pdo", "apply", str(exported), *node, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["steps"] == []

    assert main(["pdo", "show", *node, "--export", "dcf"]) == 0
    assert "[1A03sub1]" in capsys.readouterr().out.replace("sub1]", "sub1]")


def test_bad_input_exits_2_with_a_message(
    sim: tuple[SimulatedBus, list[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, opts = sim
    node = [*opts, "--node-id", "3"]
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["pdo", "apply", str(bad), *node]) == 2
    assert "not a JSON PDO layout" in capsys.readouterr().err
    assert main(["pdo", "apply", str(tmp_path / "missing.json"), *node]) == 2
    assert "no such file" in capsys.readouterr().err
    too_big = tmp_path / "big.json"
    too_big.write_text(
        json.dumps(
            {
                "pdos": [
                    {
                        "direction": "tx",
                        "number": 1,
                        "entries": ["0x6064:00", "0x606C:00", "0x6041:00"],
                    }
                ]
            }
        )
    )
    assert main(["pdo", "apply", str(too_big), *node]) == 2
    err = capsys.readouterr().err
    assert "TPDO1" in err and "64" in err
    assert main(["pdo", "apply", *node]) == 2
    assert "FILE or --template" in capsys.readouterr().err


def test_templates_and_template_apply_on_ethercat_twin(
    sim: tuple[SimulatedBus, list[str]], capsys: pytest.CaptureFixture[str]
) -> None:
    _, opts = sim
    assert main(["pdo", "templates", "--profile", "hiwin-e", "--json"]) == 0
    ids = [t["id"] for t in json.loads(capsys.readouterr().out)]
    assert "set2" in ids or len(ids) >= 3
    node = [*opts, "--node-id", "4"]
    target = next(i for i in ids if i != "factory")
    assert main(["pdo", "apply", "--template", target, *node, "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["ok"] and rep["verified"], rep
    assert main(["pdo", "apply", "--template", "no-such", *node]) == 2
    assert "no-such" in capsys.readouterr().err
