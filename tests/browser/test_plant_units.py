"""Degrees and rpm on a drive whose encoder is not the profile's (608Fh).

``servodesk serve --sim --plant FILE`` runs the generic twin on a plant file's 2^20-count
encoder; the profile's scales are written for 2^17. The engineer types a raw value on the
Parameters page and the preview must say what it means on this axis: 2^20 counts are one
revolution, 360 deg (the profile's scales would say 2880 deg).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import HarnessError, running_server, take_control

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"
ADDR = "0x6065:00"  # Following error window, inc -> deg.


@pytest.fixture(scope="module")
def plant_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    plant = Path(tmp_path_factory.mktemp("plant")) / "axis.toml"
    plant.write_text("[motor]\nencoder_counts = 1048576\n", encoding="utf-8")
    try:
        with running_server(
            args=["--plant", str(plant)], env={"SERVODESK_SIM_PROFILES": "cia402-generic"}
        ) as base:
            yield base
    except HarnessError as e:
        pytest.fail(str(e), pytrace=False)


@pytest.fixture
def plant_page(browser: Browser, plant_url: str) -> Iterator[Page]:
    yield from fresh_page(browser, plant_url)


def test_a_raw_value_is_previewed_in_the_axis_own_degrees(plant_page: Page) -> None:
    page = plant_page
    page.goto(f"/#/parameters/{SID}")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    take_control(page, SID)  # The write needs control of the drive.
    page.get_by_test_id("group-tab-position").click()
    row = page.get_by_test_id(f"param-row-{ADDR}")
    expect(row.get_by_test_id("param-value")).not_to_have_text("…")
    row.get_by_test_id(f"edit-{ADDR}").click()
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    editor.get_by_test_id("entry-raw").click()  # A raw value, previewed in degrees.
    editor.get_by_test_id("value-input").fill("1048576")
    expect(editor.get_by_test_id("value-preview")).to_contain_text("= 360 deg")
    editor.get_by_test_id("value-write").click()
    expect(editor.get_by_test_id("readback-value")).to_have_text("1048576")
    expect(editor.get_by_test_id("readback")).to_contain_text("= 360 deg")


def test_the_overview_says_which_encoder_the_units_are_for(plant_page: Page) -> None:
    plant_page.goto(f"/#/overview/{SID}")
    enc = plant_page.get_by_test_id("identity-encoder")
    expect(enc).to_contain_text("1048576 counts/rev")
    expect(enc).to_contain_text("(608Fh)")
    expect(enc).to_contain_text("not the profile’s encoder")


def test_degrees_typed_are_the_axis_own_increments(plant_page: Page) -> None:
    """Engineering entry uses the session's scale (the axis's 2^20 counts per revolution),
    not the profile's: 90 deg is a quarter of 1048576."""
    page = plant_page
    page.goto(f"/#/parameters/{SID}/position")
    expect(page.get_by_test_id("params-groups")).to_be_visible(timeout=15_000)
    take_control(page, SID)
    row = page.get_by_test_id(f"param-row-{ADDR}")
    expect(row.get_by_test_id("param-value")).not_to_have_text("…")
    row.get_by_test_id(f"edit-{ADDR}").click()
    editor = page.get_by_test_id(f"param-edit-{ADDR}")
    expect(editor.get_by_test_id("entry-eng")).to_have_attribute("aria-pressed", "true")
    editor.get_by_test_id("value-input").fill("90")
    expect(editor.get_by_test_id("value-preview")).to_contain_text("90 deg = 262144 raw")
    editor.get_by_test_id("value-write").click()
    expect(editor.get_by_test_id("readback-value")).to_have_text("262144")
