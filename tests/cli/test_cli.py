"""The command line for people and scripts: JSON shapes and exit codes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from servodesk.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_profiles_json_lists_every_family_with_counts(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "profiles", "--json")
    rows = {r["id"]: r for r in json.loads(out)}
    assert code == 0
    assert {"cia402-generic", "hiwin-e", "smartris", "ctmm04x", "lecsn-t"} <= set(rows)
    assert rows["lecsn-t"]["variables"] > 1000 and rows["smartris"]["modes"] == [3, 4]


def test_profile_json_has_the_documented_keys(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "profile", "smartris", "--json")
    p = json.loads(out)
    assert code == 0
    assert {"objects", "errors", "modes", "homing_methods", "quirks"} <= set(p)
    assert p["homing_methods"] == [] and p["problems"] == []
    e = p["errors"][0]
    assert {"code", "table", "name", "cause", "remedy"} <= set(e)


def test_od_by_address_and_pnu(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "od", "cia402-generic", "0x6040", "--json")
    (entry,) = json.loads(out)
    assert code == 0
    fields = {
        "index",
        "subindex",
        "name",
        "data_type",
        "access",
        "pdo_mapping",
        "default",
        "min",
        "max",
        "unit",
        "section",
    }
    assert fields <= set(entry) and entry["index"] == 0x6040 and entry["access"] == "rw"
    code, out, _ = run(capsys, "od", "lecsn-t", "P24640", "--json")
    assert code == 0 and json.loads(out)[0]["index"] == 24640


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["od", "nope"], "no profile 'nope'"),
        (["od", "cia402-generic", "0x9999"], "not in profile"),
        (["od", "cia402-generic", "zz"], "not an object address"),
        (["profiles", "--import", "missing.eds"], "no such file"),
        (["profile", "hiwin-e", "--export", "pdf"], "invalid choice"),
        (["nosuchcommand"], "invalid choice"),
        (["bench", "tuning", "--seeds", "1,x"], "not a comma-separated list of integers"),
        (["bench", "tuning", "--seeds", "2,2"], "distinct seeds"),
    ],
)
def test_bad_input_exits_2_with_a_message_not_a_traceback(argv: list[str], message: str) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "servodesk", *argv], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 2
    assert message in r.stderr and "Traceback" not in r.stderr


def test_bad_settings_exit_2_with_one_line_each_not_a_traceback(tmp_path: Path) -> None:
    # It was pydantic's ValidationError traceback, naming fields rather than variables.
    bad = {
        "SERVODESK_DRIFT_WEBHOOK": "ftp://x",
        "SERVODESK_SIM_WITHHOLD": "nonsense",
        "SERVODESK_DEADMAN_MS": "soon",
        "SERVODESK_LOG_LEVEL": "loud",
    }
    env = {**os.environ, "SERVODESK_DATA_DIR": str(tmp_path), **bad}
    for argv in (["serve"], ["profiles"]):
        r = subprocess.run(
            [sys.executable, "-m", "servodesk", *argv],
            capture_output=True,
            text=True,
            timeout=60,
            env=env,
        )
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        lines = r.stderr.splitlines()
        assert len(lines) == len(bad), r.stderr
        said = {line.split(": ")[2]: line for line in lines}  # servodesk: error: VAR: ...
        assert set(said) == set(bad), r.stderr
        assert (
            "'ftp://x' is not an http:// or https:// URL; write an http"
            in said["SERVODESK_DRIFT_WEBHOOK"]
        )
        assert "write profile=address, e.g. smartris=0x607F:00" in said["SERVODESK_SIM_WITHHOLD"]
        assert (
            "'soon' is not a whole number; write a whole number from 50 to 5000 (default 250)"
            in said["SERVODESK_DEADMAN_MS"]
        )
        assert "'loud' is not a log level; write one of" in said["SERVODESK_LOG_LEVEL"]


@pytest.mark.parametrize("argv", [["openapi"], ["od", "lecsn-t"]])
def test_a_reader_that_stops_early_ends_the_command_quietly(argv: list[str]) -> None:
    # `servodesk openapi | head`: a BrokenPipeError traceback on stderr. Both print far more
    # than a pipe holds (64 KiB), so the writer meets the closed pipe.
    p = subprocess.Popen(
        [sys.executable, "-m", "servodesk", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert p.stdout is not None and p.stderr is not None
    assert p.stdout.read(100)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 141, err  # 128 + SIGPIPE, as the shell reports for `seq`.
    assert err == ""


def test_export_refuses_to_overwrite_and_writes_atomically(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "generic.eds"
    assert run(capsys, "profile", "cia402-generic", "--export", "eds", "-o", str(out))[0] == 0
    first = out.read_text()
    assert "[1018sub1]" in first
    code, _, err = run(capsys, "profile", "cia402-generic", "--export", "eds", "-o", str(out))
    assert code == 2 and "exists" in err and out.read_text() == first
    assert list(tmp_path.iterdir()) == [out]  # No temporary file left behind.


def test_a_data_directory_that_cannot_be_made_is_an_error_not_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # A file where the data directory should be (or no permission): exit 2 with the setting
    # to fix. It was a NotADirectoryError traceback from the store's mkdir.
    (tmp_path / "f").write_text("x")
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path / "f" / "data"))
    out = tmp_path / "b.json"
    code, _, err = run(capsys, "backup", "-o", str(out), "--channel", "nothing-here")
    assert code == 2 and "cannot use the data directory" in err, err
    assert "SERVODESK_DATA_DIR" in err and "Traceback" not in err
    assert not out.exists()


def test_scan_lists_the_nodes_of_a_can_bus_with_their_profiles(
    capsys: pytest.CaptureFixture[str],
    channel: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from servodesk.sim.bus import SimulatedBus

    # A scan keeps nothing: it works where the data directory cannot be made, and makes none.
    (tmp_path / "f").write_text("a file where a directory would go")
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path / "f" / "data"))
    with SimulatedBus.start(drives=[("cia402-generic", 1), ("smartris", 3)], channel=channel):
        code, out, err = run(capsys, "scan", "--channel", channel, "--json")
        assert code == 0, err
        nodes = json.loads(out)["nodes"]
        assert [(n["node_id"], n["profile_id"]) for n in nodes] == [
            (1, "cia402-generic"),
            (3, "smartris"),
        ]
        code, out, _ = run(capsys, "scan", "--channel", channel)
        assert code == 0
        assert "node   3" in out and "profile smartris" in out and "vendor_id " in out
    code, _, err = run(capsys, "scan", "--channel", f"{channel}-empty", "--wait", "0.1")
    assert code == 0 and "no node answered" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


@pytest.mark.parametrize(
    ("argv", "text"),
    [
        (["--interface", "profinet"], "dcp identify"),
        (["--interface", "slmp"], "slmp has no scan"),
        (["--interface", "nope"], "unknown interface 'nope'"),
        (["--wait", "9"], "outside 0.05-3 s"),
        (["--interface", "ethercat", "--channel", "sdnothere0"], "no network interface"),
    ],
)
def test_scan_refuses_what_it_cannot_scan(
    capsys: pytest.CaptureFixture[str], argv: list[str], text: str
) -> None:
    code, _, err = run(capsys, "scan", *argv)
    assert code == 2 and text in err and "Traceback" not in err, err
