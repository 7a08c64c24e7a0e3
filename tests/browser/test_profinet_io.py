"""Issue 47: jog and a move through the UI on the PROFINET twin, over servodesk's own IO AR.

``serve --sim`` with ``SERVODESK_SIM_DCP=1`` puts the LECSN-T twin's RT frames behind a veth
pair (root, as in CI), so the PDO page can start cyclic data as the drive's IO controller
(docs/profinet.md, "Cyclic data"). A fresh twin has standard telegram 1, which carries
PROFIdrive's STW1 and no controlword: the page's telegram choice sets servodesk's IO AR up with
telegram 102 (its expected submodule, as a PLC's configuration tool does, 004 §20.1.1), the
drive's P922 follows, and the Operation page's servo on, jog and move then go out in the
setpoint telegram every cycle.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.conftest import fresh_page
from tests.browser.harness import running_server, shown_int, take_control

pytestmark = [pytest.mark.browser, pytest.mark.timeout(180)]


@pytest.fixture(scope="module")
def profinet_url() -> Iterator[str]:
    env = {"SERVODESK_SIM_DCP": "1", "SERVODESK_SIM_PROFILES": "lecsn-t"}
    with running_server(env=env) as base:
        yield base


@pytest.fixture
def pn_page(browser: Browser, profinet_url: str) -> Iterator[Page]:
    yield from fresh_page(browser, profinet_url)


def test_jog_and_a_move_through_the_ui_over_profinet_cyclic_io(pn_page: Page) -> None:
    page = pn_page
    (lecsn,) = page.request.get("/api/v1/sessions").json()
    sid = lecsn["id"]
    assert lecsn["fieldbus"] == "profinet"
    # The twin's RT frames are reachable (root made the veth pair): cyclic data is offered.
    cyclic = page.request.get(f"/api/v1/sessions/{sid}/pdo/cyclic").json()
    assert cyclic["unavailable"] is None, (cyclic["unavailable"], lecsn["note"])

    page.goto(f"/#/pdo/{sid}")
    take_control(page, sid)
    telegram = page.get_by_test_id("pdo-cyclic-telegram")
    # The drive's telegram first; telegram 1 cannot enable the drive from the Operation page.
    expect(telegram).to_have_value("1")
    note = page.get_by_test_id("pdo-cyclic-telegram-note")
    expect(note).to_contain_text("no controlword (6040h)")
    expect(note).to_contain_text("(100, 102, 103)")
    telegram.select_option("102")
    expect(note).to_have_count(0)
    # PROFINET offers the send clock's cycles only: the 10 ms default became 8 ms.
    period = page.get_by_test_id("pdo-cyclic-period-choice")
    expect(period).to_have_value("8")
    period.select_option("2")
    page.get_by_test_id("pdo-cyclic-start").click()
    expect(page.get_by_test_id("pdo-cyclic-state")).to_have_text("running", timeout=15_000)
    # The drive took the AR's telegram: the page shows telegram 102's layout now.
    expect(page.get_by_test_id("pdo-telegram-select")).to_have_value("102", timeout=10_000)
    info = page.request.get(f"/api/v1/sessions/{sid}").json()
    assert "IO controller AR (ARType 0001h" in info["ar"], info["ar"]

    page.goto(f"/#/operation/{sid}")
    expect(page.get_by_test_id("operation-page")).to_be_visible()
    expect(page.get_by_test_id("socket-banner")).to_have_count(0, timeout=10_000)
    take_control(page, sid)
    state = page.get_by_test_id("op-state")
    expect(state).not_to_have_text("—")
    page.get_by_test_id("servo-on").click()
    try:
        expect(state).to_have_text("Operation enabled", timeout=10_000)
    except AssertionError as exc:
        # Say what the IO AR did meanwhile (a watchdog expiry ends it and disables the drive).
        link = page.request.get(f"/api/v1/sessions/{sid}/pdo/cyclic").json().get("link")
        raise AssertionError(f"{exc}\nIO AR: {link}") from None
    page.get_by_test_id("units-raw").click()

    # Jog: held, the axis runs; let go, it stands.
    before = shown_int(page, "op-position")
    page.get_by_test_id("tab-jog").click()
    page.get_by_test_id("jog-plus").hover()
    page.mouse.down()
    expect(page.get_by_test_id("motion-status")).to_have_attribute("data-active", "true")
    page.wait_for_timeout(1000)
    assert shown_int(page, "op-velocity") > 0
    page.mouse.up()
    expect(page.get_by_test_id("op-velocity")).to_have_text("0", timeout=3_000)
    expect(page.get_by_test_id("motion-status")).to_have_attribute("data-state", "halted")
    jogged = shown_int(page, "op-position")
    assert jogged > before, (before, jogged)

    # A relative move by 20 000 pulses: controlword and 607Ah in the setpoint telegram.
    page.get_by_test_id("tab-move").click()
    page.get_by_test_id("move-mode-relative").click()
    page.get_by_test_id("move-target").fill("20000")
    page.get_by_test_id("move-start").click()
    expect(page.get_by_test_id("motion-status")).to_have_attribute(
        "data-state", "reached", timeout=20_000
    )
    page.wait_for_timeout(300)
    moved = shown_int(page, "op-position")
    assert abs(moved - jogged - 20_000) <= 50, (jogged, moved)
    expect(state).to_have_text("Operation enabled")

    # It all went over the IO AR: frames every 2 ms, the link healthy, no missing frame.
    status = page.request.get(f"/api/v1/sessions/{sid}/pdo/cyclic").json()
    assert status["running"] and status["telegram"] == 102, status
    assert status["link"]["state"] == "ok" and status["link"]["cycle_ms"] == 2, status["link"]
    assert status["frames_per_s"] > 300, status["frames_per_s"]

    page.get_by_test_id("servo-off").click()
    expect(state).not_to_have_text("Operation enabled", timeout=10_000)
    page.goto(f"/#/pdo/{sid}")
    page.get_by_test_id("pdo-cyclic-stop").click()
    expect(page.get_by_test_id("pdo-cyclic-state")).to_have_text("stopped", timeout=10_000)
    info = page.request.get(f"/api/v1/sessions/{sid}").json()
    assert info["ar"] == "IO supervisor AR with device access (ARType 0006h)", info["ar"]
