"""Plant files (docs/tuning.md, "Plant files"; model/plantfile.py): defaults, values, every
refusal with its message, the hash, and ``servodesk sim --plant``."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import canopen
import pytest

from servodesk.cli import main
from servodesk.errors import ServodeskError, ValidationError
from servodesk.model.plant import TwoMassMechanics
from servodesk.model.plantfile import (
    PlantFileError,
    PlantSpec,
    load_plant_file,
    parse_plant_toml,
    spec_keys,
)
from servodesk.sim.bus import SimulatedBus

FULL = """
[motor]
inertia = 5e-5
rated_torque = 2.0
peak_torque = 6.0
encoder_counts = 131072
current_loop_hz = 1500

[load]
inertia_ratio = 3
coulomb = 0.01
viscous = 2e-4
gravity = -0.1

[compliance]
resonance_hz = 250
damping = 0.05

[noise]
torque = 0.002

[loop]
rate_hz = 8000
"""


def test_an_empty_file_is_the_documented_default_rigid_axis() -> None:
    spec = parse_plant_toml("")
    assert spec == PlantSpec()
    assert (spec.motor_inertia, spec.rated_torque, spec.peak_torque) == (3.7e-5, 1.27, 4.46)
    assert (spec.encoder_counts, spec.current_loop_hz) == (1048576, 2000.0)
    assert (spec.inertia_ratio, spec.coulomb, spec.viscous, spec.gravity) == (10.0, 0.02, 0, 0)
    assert spec.rigid and spec.resonance_hz is None
    assert (spec.noise_torque, spec.loop_rate_hz) == (0.005, 16000)
    p = spec.plant_params(seed=3)
    # Torques given as fractions of the peak torque become N m.
    assert p.coulomb == pytest.approx(0.02 * 4.46)
    assert p.torque_noise == pytest.approx(0.005 * 4.46)
    assert p.load_inertia == pytest.approx(10 * 3.7e-5)
    assert p.current_tau == pytest.approx(1.0 / (2 * math.pi * 2000))
    assert (p.counts_per_rev, p.seed, p.resonance_hz) == (1 << 20, 3, None)


def test_every_key_is_read() -> None:
    spec = parse_plant_toml(FULL)
    assert spec == PlantSpec(
        motor_inertia=5e-5,
        rated_torque=2.0,
        peak_torque=6.0,
        encoder_counts=131072,
        current_loop_hz=1500.0,
        inertia_ratio=3.0,
        coulomb=0.01,
        viscous=2e-4,
        gravity=-0.1,
        resonance_hz=250.0,
        damping=0.05,
        noise_torque=0.002,
        loop_rate_hz=8000,
    )
    p = spec.plant_params()
    assert p.gravity == pytest.approx(-0.6) and p.antiresonance_hz == pytest.approx(125.0)
    # The keys the module documents are the keys it reads.
    assert spec_keys() == {
        "motor": ("inertia", "rated_torque", "peak_torque", "encoder_counts", "current_loop_hz"),
        "load": ("inertia_ratio", "coulomb", "viscous", "gravity"),
        "compliance": ("resonance_hz", "damping"),
        "noise": ("torque",),
        "loop": ("rate_hz",),
    }


def test_a_compliance_section_makes_a_two_mass_axis_with_its_defaults() -> None:
    spec = parse_plant_toml("[compliance]\n")
    assert (spec.resonance_hz, spec.damping, spec.rigid) == (400.0, 0.03, False)
    from servodesk.model.plant import Plant

    plant = Plant(spec.plant_params())
    assert isinstance(plant.mechanics, TwoMassMechanics)
    assert parse_plant_toml("[compliance]\ndamping = 0.1").resonance_hz == 400.0


def _err(text: str) -> str:
    with pytest.raises(PlantFileError) as info:
        parse_plant_toml(text, source="x.toml")
    return info.value.message


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("[motors]\ninertia = 1e-5", "unknown section [motors]"),
        ("inertia = 1e-5", "unknown key inertia"),
        ("motor = 1", "motor = 1 must be a section [motor]"),
        ("[motor]\ninertia_kg = 1e-5", "unknown key [motor] inertia_kg"),
        ("[motor]\ninertia = 'big'", "[motor] inertia = 'big' must be a number (1e-07..1 kg m²)"),
        ("[motor]\ninertia = true", "[motor] inertia = True must be a number"),
        ("[motor]\ninertia = 2.0", "[motor] inertia = 2.0 is out of range (1e-07..1 kg m²)"),
        ("[motor]\ninertia = 0", "[motor] inertia = 0 is out of range"),
        ("[motor]\nrated_torque = 0.001", "[motor] rated_torque = 0.001 is out of range"),
        ("[motor]\npeak_torque = 5000", "[motor] peak_torque = 5000 is out of range"),
        (
            "[motor]\nrated_torque = 3\npeak_torque = 2",
            "[motor] peak_torque = 2 is out of range (3..3000 N m: at least rated_torque)",
        ),
        ("[motor]\nencoder_counts = 1e6", "[motor] encoder_counts = 1000000.0 must be an integer"),
        ("[motor]\nencoder_counts = 100", "encoder_counts = 100 is out of range (256..2^31"),
        ("[motor]\ncurrent_loop_hz = 50", "[motor] current_loop_hz = 50 is out of range"),
        ("[load]\ninertia_ratio = 0", "[load] inertia_ratio = 0 is out of range (0.1..100)"),
        ("[load]\ninertia_ratio = 101", "[load] inertia_ratio = 101 is out of range"),
        ("[load]\ncoulomb = -0.1", "[load] coulomb = -0.1 is out of range (0..0.5 of peak)"),
        ("[load]\nviscous = 2", "[load] viscous = 2 is out of range (0..1 N m s/rad)"),
        ("[load]\ngravity = 0.9", "[load] gravity = 0.9 is out of range (-0.8..0.8 of peak)"),
        (
            "[compliance]\nresonance_hz = 5000",
            "[compliance] resonance_hz = 5000 is out of range (10..4000 Hz)",
        ),
        (
            "[compliance]\nresonance_hz = 2500",
            "[compliance] resonance_hz = 2500 is out of range (10..2000 Hz: at most [loop] "
            "rate_hz / 8, 16000 Hz)",
        ),
        (
            "[compliance]\nresonance_hz = 600\n[loop]\nrate_hz = 4000",
            "resonance_hz = 600 is out of range (10..500 Hz",
        ),
        ("[compliance]\nresonance_hz = 5", "[compliance] resonance_hz = 5 is out of range"),
        ("[compliance]\ndamping = 1.5", "[compliance] damping = 1.5 is out of range (0..1)"),
        ("[compliance]\ndamping = 'low'", "[compliance] damping = 'low' must be a number"),
        ("[noise]\ntorque = 0.2", "[noise] torque = 0.2 is out of range (0..0.1 of peak)"),
        ("[noise]\ntorque = nan", "[noise] torque = nan is out of range"),
        ("[loop]\nrate_hz = 500", "[loop] rate_hz = 500 is out of range (1000..32000 Hz)"),
        ("[loop]\nrate_hz = 40000", "[loop] rate_hz = 40000 is out of range"),
        ("[loop]\nrate_hz = 12500", "[loop] rate_hz = 12500 must be a multiple of 1000 Hz"),
        ("[loop]\nrate_hz = 16000.5", "[loop] rate_hz = 16000.5 must be a multiple of 1000 Hz"),
        ("[loop]\nrate = 16000", "unknown key [loop] rate (keys: rate_hz)"),
        ("[motor\ninertia = 1", "not valid TOML"),
        ("[motor]\ninertia = [1, 2]", "[motor] inertia = [1, 2] must be a number"),
    ],
)
def test_bad_files_are_refused_naming_the_key_and_the_range(text: str, expected: str) -> None:
    message = _err(text)
    assert message.startswith("plant file x.toml: ")
    assert expected in message, message


def test_the_error_is_a_user_input_error() -> None:
    # ValidationError: the CLI exits 2, the API answers 400 (api/errors.py).
    assert issubclass(PlantFileError, ValidationError)
    with pytest.raises(ServodeskError) as info:
        parse_plant_toml("[load]\ngravity = 1")
    assert isinstance(info.value, PlantFileError) and info.value.field == "load.gravity"


def test_files_that_cannot_be_read(tmp_path: Path) -> None:
    with pytest.raises(PlantFileError, match=r"plant file .*missing\.toml: cannot read"):
        load_plant_file(tmp_path / "missing.toml")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe[motor]")
    with pytest.raises(PlantFileError, match="not UTF-8"):
        load_plant_file(binary)
    good = tmp_path / "axis.toml"
    good.write_text(FULL, encoding="utf-8")
    assert load_plant_file(good) == parse_plant_toml(FULL)
    bad = tmp_path / "bad.toml"
    bad.write_text("[load]\ninertia_ratio = 200\n", encoding="utf-8")
    with pytest.raises(PlantFileError, match=r"^plant file bad\.toml: \[load\] inertia_ratio"):
        load_plant_file(bad)


def test_the_harsh_plants_shipped_in_bench_load_as_their_names_say() -> None:
    """bench/plants/soft-<ratio>x-<resonance>hz-d<damping>.toml (docs/tuning.md): each file
    loads and is the heavy, soft axis its name promises, with an anti-resonance below 25 Hz."""
    files = sorted((Path(__file__).parents[2] / "bench" / "plants").glob("*.toml"))
    assert len(files) == 7
    for f in files:
        ratio, fr, damping = f.stem.removeprefix("soft-").split("-")
        spec = load_plant_file(f)
        assert spec.inertia_ratio == float(ratio.removesuffix("x"))
        assert spec.resonance_hz == float(fr.removesuffix("hz"))
        assert spec.damping == float(damping.removeprefix("d"))
        assert spec.resonance_hz / math.sqrt(1.0 + spec.inertia_ratio) < 25.0


def test_the_hash_follows_the_values_not_the_spelling() -> None:
    a = parse_plant_toml("[load]\ninertia_ratio = 3\n[loop]\nrate_hz = 8000")
    b = parse_plant_toml("[loop]\nrate_hz = 8000\n\n[load]\ninertia_ratio = 3.0  # three\n")
    assert a.sha256() == b.sha256() and len(a.sha256()) == 64
    assert a.sha256() != parse_plant_toml("[load]\ninertia_ratio = 3.1").sha256()
    # A rigid axis has no damping: the hash ignores it; a compliant one does not.
    assert PlantSpec(damping=0.5).sha256() == PlantSpec().sha256()
    assert PlantSpec(resonance_hz=400, damping=0.5).sha256() != PlantSpec(resonance_hz=400).sha256()
    # Stable across runs and versions (cached results are keyed by it): change only on purpose.
    assert PlantSpec().sha256() == (
        "b7058af99168271b498cdca5bb857534219c5dffa9e47b798824e0d91a8eb4d5"
    )
    full = parse_plant_toml(FULL)
    assert parse_plant_toml(full.to_toml()) == full


# ---------------------------------------------------------------------- servodesk sim --plant


def test_cli_refuses_a_bad_plant_file_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "axis.toml"
    bad.write_text("[compliance]\nresonance_hz = 5000\n", encoding="utf-8")
    code = main(["sim", "--plant", str(bad), "--channel", "plant-cli-test"])
    err = capsys.readouterr().err
    assert code == 2
    assert "plant file axis.toml: [compliance] resonance_hz = 5000 is out of range" in err
    assert "Traceback" not in err
    assert main(["sim", "--plant", str(tmp_path / "nope.toml")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_serve_refuses_a_bad_plant_file_or_one_without_sim_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Refused before anything starts: no server, no port taken.
    bad = tmp_path / "axis.toml"
    bad.write_text("[noise]\ntorque = -1\n", encoding="utf-8")
    assert main(["serve", "--sim", "--plant", str(bad), "--port", "1"]) == 2
    err = capsys.readouterr().err
    assert "plant file axis.toml: [noise] torque = -1" in err and "Traceback" not in err
    good = tmp_path / "good.toml"
    good.write_text("", encoding="utf-8")
    assert main(["serve", "--plant", str(good)]) == 2
    assert "--plant needs --sim" in capsys.readouterr().err


def test_bus_with_a_plant_serves_its_loop_rate_over_sdo(channel: str) -> None:
    spec = parse_plant_toml("[compliance]\nresonance_hz = 300\n[loop]\nrate_hz = 8000")
    bus = SimulatedBus.start(drives=[("cia402-generic", 9)], channel=channel, plant=spec)
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="virtual", channel=channel)
    try:
        drive = bus.drives[0]
        assert drive.loop_rate_hz == 8000 and drive.plant_params.resonance_hz == 300
        assert drive.plant_params.counts_per_rev == 1 << 20 and drive.servo is not None
        # The profile's speeds and switches keep their meaning in revolutions.
        assert drive.sim_settings.max_velocity == pytest.approx(1_000_000 * 8)
        node = net.add_node(9)
        assert int.from_bytes(node.sdo.upload(0x2108, 0), "little") == 8000
        assert int.from_bytes(node.sdo.upload(0x608F, 1), "little") == 1 << 20

        # So do the objects counted in increments: 607Fh is 7.6 rev/s as on the profile's
        # 2^17-count twin, not 0.95 rev/s; 607Dh's +-2^31 ("no limit") stays in its type.
        def read(index: int, sub: int = 0, signed: bool = False) -> int:
            return int.from_bytes(node.sdo.upload(index, sub), "little", signed=signed)

        assert read(0x607F) == 8 * 1_000_000 and read(0x6081) == 8 * 200_000
        assert read(0x6083) == read(0x6084) == 8 * 1_000_000 and read(0x6065) == 8 * 20_000
        assert read(0x607D, 1, signed=True) == -(1 << 31)
        assert read(0x607D, 2, signed=True) == (1 << 31) - 1
    finally:
        net.disconnect()
        bus.stop()


def test_cli_serves_the_plant_until_interrupted(tmp_path: Path) -> None:
    plant = tmp_path / "axis.toml"
    plant.write_text("[compliance]\nresonance_hz = 400\n", encoding="utf-8")
    proc = subprocess.Popen(
        [sys.executable, "-m", "servodesk", "sim", "--plant", str(plant), "--channel", "p-cli"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline() for _ in range(2)]
        assert "serving cia402-generic" in lines[0]
        assert "plant" in lines[1] and "resonance 400 Hz" in lines[1] and "16000 Hz" in lines[1]
        time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
