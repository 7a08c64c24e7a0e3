"""The browser UI against the real backend and a simulated CiA 402 drive.

What a commissioning engineer does first: open the simulated drive's session from the
Connect page, enable it and see "Operation enabled"; then read and write objects on the
Object access page and get the drive's own refusal (SDO abort text) when writing a
read-only object. Changing a drive needs control: the engineer takes it first with the
header's Take control.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from tests.browser.harness import take_control

pytestmark = pytest.mark.browser

PROFILE = "cia402-generic"


def open_generic_session(page: Page) -> str:
    """Open the simulated generic drive from the Connect page; returns its session id."""
    page.goto("/#/connect")
    expect(page.get_by_test_id("page-connect")).to_be_visible()
    rows = page.locator(f'tr[data-profile="{PROFILE}"]')
    # The simulated drives' sessions are listed once the socket (or GET /sessions) answered.
    try:
        rows.first.wait_for(state="visible", timeout=5_000)
    except Exception:
        # No open session for the drive: find it on the bus and open it.
        page.get_by_test_id("scan-bus").click()
        node = page.get_by_test_id("scan-results").locator("tr", has_text=PROFILE).first
        node.get_by_role("button", name="Open").click()
    else:
        rows.first.get_by_role("button", name="Open").click()
    page.wait_for_url(re.compile(r"#/overview/"))
    sid = page.url.split("#/overview/", 1)[1]
    expect(page.get_by_test_id("header-drive-name")).to_be_visible()
    return sid


def test_enable_reaches_operation_enabled(page: Page) -> None:
    sid = open_generic_session(page)
    take_control(page, sid)
    state = page.get_by_test_id("drive-state")
    expect(state).not_to_have_text("—")

    page.get_by_test_id("cmd-enable").click()
    expect(state).to_have_text("Operation enabled", timeout=10_000)
    expect(page.get_by_test_id("header-state")).to_have_text("Operation enabled")
    expect(page.get_by_test_id("diagram-state-operation-enabled")).to_have_attribute(
        "data-active", "true"
    )
    # Statusword bit 2 (Operation enabled) is lit in the bit table.
    expect(page.get_by_test_id("sw-bit-2")).to_have_attribute("data-set", "1")

    page.get_by_test_id("cmd-disable").click()
    expect(state).to_have_text("Switch on disabled", timeout=10_000)


def test_write_read_only_object_shows_abort(page: Page) -> None:
    sid = open_generic_session(page)
    page.get_by_test_id("nav-objects").click()
    take_control(page, sid)
    page.get_by_test_id("object-address").fill("0x6041")
    page.get_by_test_id("object-value").fill("1")
    page.get_by_test_id("object-write").click()

    error = page.get_by_test_id("object-error")
    expect(error).to_contain_text("Attempt to write a read only object")
    expect(page.get_by_test_id("object-error-code")).to_have_text("0x06010002")
    # The failure is also in the history, marked as a write.
    expect(page.get_by_test_id("history-row").first).to_contain_text("0x6041:00")


def test_write_6081_and_read_it_back(page: Page) -> None:
    sid = open_generic_session(page)
    page.get_by_test_id("nav-objects").click()
    take_control(page, sid)
    address = page.get_by_test_id("object-address")
    value = page.get_by_test_id("object-value")

    address.fill("0x6081")
    # Raw entry (inc/s): 6081h offers rpm too once the session's profile is known.
    page.get_by_test_id("object-entry-raw").click()
    value.fill("1500")
    page.get_by_test_id("object-write").click()
    expect(page.get_by_test_id("object-value-dec")).to_contain_text("1500")

    # Read it back in a separate access, after clearing what the write showed.
    value.fill("")
    address.fill("6081h.0")
    page.get_by_test_id("object-read").click()
    expect(page.get_by_test_id("object-result-address")).to_have_text("0x6081:00")
    expect(page.get_by_test_id("object-value-dec")).to_contain_text("1500")
    expect(value).to_have_value("1500")

    # Hex entry: 7D0 is 2000.
    page.get_by_test_id("value-mode-hex").click()
    value.fill("7D0")
    page.get_by_test_id("object-write").click()
    expect(page.get_by_test_id("object-value-dec")).to_contain_text("2000")
    expect(page.get_by_test_id("object-value-hex")).to_have_text("0x000007D0")
    expect(page.get_by_test_id("history-row")).to_have_count(3)


@pytest.mark.parametrize("width", [1280, 1024])
def test_the_drive_state_stays_whole_in_the_header_on_a_laptop_screen(
    page: Page, width: int
) -> None:
    # The LECSN-T's device name and link line are long. At 1400 px its state pill was cut to
    # "Switch on d": the name and the node line now give way (ellipsis, full text in their
    # tooltips), the state and the SIM badge never do.
    page.set_viewport_size({"width": width, "height": 800})
    page.goto("/#/overview/lecsn-t-1")
    pill = page.get_by_test_id("header-state")
    expect(pill).to_have_text(re.compile(r"\w+ \w+"))
    # The header is whole before it is measured: the user menu (single-user mode here)
    # arrives with /auth/me and takes its room beside the drive's title.
    expect(page.get_by_test_id("user-menu")).to_be_visible()
    title = page.locator(".drive-title")

    def inside() -> tuple[bool, object]:
        box, area = pill.bounding_box(), title.bounding_box()
        assert box is not None and area is not None
        fits = box["x"] >= area["x"] and box["x"] + box["width"] <= area["x"] + area["width"] + 0.5
        return fits, (box, area)

    # Measured once the header has settled: it is laid out again as the session's details
    # and live state arrive, and a clean-clone run measured the pill outside once (the same
    # code passed the run before). A pill that stays outside for 5 s still fails.
    deadline = time.monotonic() + 5.0
    fits, boxes = inside()
    while not fits and time.monotonic() < deadline:
        page.wait_for_timeout(100)
        fits, boxes = inside()
    assert fits, boxes
    assert pill.evaluate("e => e.scrollWidth <= e.clientWidth")
    name = page.get_by_test_id("header-drive-name")
    # The name the card reports (I&M0 order ID, 004 §20.4.4), with the profile's.
    expect(name).to_have_attribute(
        "title", "MR-J4-TM (SMC LECSN-T servo amplifier (LEC-S-NP PROFINET))"
    )
    expect(page.locator(".drive-meta")).to_have_attribute(
        "title", re.compile(r"^DO-ID 1 · profinet · ")
    )


def test_the_open_sessions_fit_a_laptop_screen(page: Page) -> None:
    # With the five twins open, the sessions table ran past its card at 1280 px and the Close
    # buttons stood outside it. Fieldbus and bus now share a column; a table still too wide
    # for a smaller screen scrolls inside its card.
    page.set_viewport_size({"width": 1280, "height": 800})
    page.goto("/#/connect")
    close = page.get_by_test_id("session-close-lecsn-t-1")
    expect(close).to_be_visible()
    wrap = page.locator(".table-scroll").filter(has=page.get_by_test_id("sessions"))
    assert wrap.evaluate("e => e.scrollWidth <= e.clientWidth")
    box, card = close.bounding_box(), wrap.bounding_box()
    assert box is not None and card is not None
    assert box["x"] + box["width"] <= card["x"] + card["width"] + 0.5
    # Not only as the rows read now: the table's narrowest layout leaves room for a page
    # scrollbar and longer states (a CI run found it 7 px over, with a scrollbar beside it
    # and the profile in a column of its own; it is now the session's second line).
    need = wrap.evaluate(
        """e => { const t = e.querySelector('table'); const w = t.style.width;
                  t.style.width = '1px'; const n = t.getBoundingClientRect().width;
                  t.style.width = w; return n; }"""
    )
    assert need <= wrap.evaluate("e => e.clientWidth") - 60, need
    # The NMT state says what it rests on: PROFINET has none; an unknown one on CANopen says
    # why (a twin may send no heartbeat, and a test before this one may have sent it an NMT
    # command).
    expect(page.get_by_test_id("session-nmt-lecsn-t-1")).to_have_attribute(
        "title", re.compile(r"^No NMT on PROFINET")
    )
    # Issue 48: no bare "unknown": what each fieldbus has (PROFINET AR, SLMP link), and on
    # CANopen without a heartbeat that none is reported.
    expect(page.get_by_test_id("session-nmt-lecsn-t-1")).to_have_text(
        "AR up (servodesk's supervisor AR)"
    )
    expect(page.get_by_test_id("session-nmt-ctmm04x-1")).to_have_text("SLMP link answering")
    nmt = page.get_by_test_id("session-nmt-hiwin-e-2")
    expect(nmt).not_to_have_text(re.compile(r"unknown"))
    if "not reported" in nmt.inner_text():
        expect(nmt).to_have_attribute("title", re.compile(r"no heartbeat .* \(1017h\) is 0"))
    else:
        expect(nmt).to_have_attribute("title", re.compile(r"from the drive's last heartbeat"))
    smartris = page.get_by_test_id("session-nmt-smartris-3")
    expect(smartris).to_have_text(re.compile(r"^NMT (preop|operational|stopped)$"))
    expect(smartris).to_have_attribute("title", re.compile(r"^NMT state \w+: from the drive's"))


def test_the_ctmm04x_is_on_slmp_and_the_form_takes_a_station_and_an_axis(page: Page) -> None:
    # serve --sim opens the CTMM04x twin over SLMP (docs/slmp.md); the Connect form reaches a
    # station by host:port and an axis, with no bitrate and no scan.
    page.set_viewport_size({"width": 1280, "height": 800})
    page.goto("/#/connect")
    row = page.get_by_test_id("session-row-ctmm04x-1")
    expect(row).to_contain_text(re.compile(r"cclink-ie-tsn\s*slmp:127\.0\.0\.1:\d+"))
    expect(page.get_by_test_id("session-nmt-ctmm04x-1")).to_have_attribute(
        "title", re.compile(r"manager's command \(003 §3-3\)")
    )
    where = re.search(r"slmp:(127\.0\.0\.1:\d+)", row.inner_text())
    assert where is not None

    page.get_by_test_id("bus-interface").select_option("slmp")
    expect(page.get_by_test_id("bus-channel")).to_have_value("192.168.0.250:5010")
    expect(page.get_by_test_id("bus-bitrate")).to_be_disabled()
    expect(page.get_by_test_id("scan-bus")).to_be_disabled()
    axis = page.get_by_test_id("bus-node-id")
    assert axis.locator("option").all_inner_texts() == [
        "X (node id 1, multidrop 0)",
        "Y (node id 2, multidrop 1)",
        "Z (node id 3, multidrop 2)",
        "U (node id 4, multidrop 3)",
    ]
    page.get_by_test_id("bus-channel").fill(where.group(1))
    axis.select_option("2")  # The twin's station has axis X only.
    page.get_by_test_id("open-session").click()
    notice = page.get_by_test_id("notice-error")
    expect(notice).to_contain_text("has no axis Y")
    expect(page).to_have_url(re.compile(r"#/connect"))

    # Its PDO page says there is no cyclic data over SLMP before anyone presses Start.
    page.goto("/#/pdo/ctmm04x-1")
    expect(page.get_by_test_id("pdo-cyclic-unavailable")).to_contain_text("manager only")
    expect(page.get_by_test_id("pdo-cyclic-start")).to_be_disabled()


def test_a_profinet_drive_is_opened_by_its_address_and_do_id(page: Page) -> None:
    # The LECSN-T twin of serve --sim is a PROFINET IO device on a loopback UDP port; the
    # Connect page reaches such a drive by its IP address and DO-ID, with no bitrate and no
    # scan (docs/profinet.md).
    page.set_viewport_size({"width": 1280, "height": 800})
    page.goto("/#/connect")
    row = page.get_by_test_id("session-row-lecsn-t-1")
    expect(row).to_contain_text(re.compile(r"profinet\s*profinet:127\.0\.0\.1:\d+"))
    expect(page.get_by_test_id("session-nmt-lecsn-t-1")).to_have_attribute(
        "title", re.compile(r"No NMT on PROFINET")
    )
    where = re.search(r"profinet:(127\.0\.0\.1:\d+)", row.inner_text())
    assert where is not None

    page.get_by_test_id("bus-node-id").fill("7")
    page.get_by_test_id("bus-interface").select_option("profinet")
    expect(page.get_by_test_id("bus-channel")).to_have_value("192.168.0.10")
    expect(page.get_by_test_id("bus-bitrate")).to_be_disabled()
    expect(page.get_by_test_id("scan-bus")).to_be_disabled()
    node = page.get_by_test_id("bus-node-id")
    expect(node).to_have_value("1")  # The LECSN-T's DO-ID.
    expect(page.locator("label", has=node)).to_contain_text("DO-ID")
    page.get_by_test_id("bus-channel").fill(where.group(1))
    node.fill("2")  # The twin has drive object 1 only.
    page.get_by_test_id("open-session").click()
    expect(page.get_by_test_id("notice-error")).to_contain_text("no drive object 2")
    expect(page).to_have_url(re.compile(r"#/connect"))

    # Its PDO page says there is no cyclic data for a supervisor, before anyone presses Start.
    page.goto("/#/pdo/lecsn-t-1")
    expect(page.get_by_test_id("pdo-cyclic-unavailable")).to_contain_text("GSD file")
    # PROFINET has no NMT: the header does not show "NMT unknown".
    expect(page.get_by_test_id("pdo-summary")).to_contain_text("big-endian")
    expect(page.get_by_test_id("pdo-summary")).not_to_contain_text("NMT")
    expect(page.get_by_test_id("pdo-cyclic-start")).to_be_disabled()
    # The telegram is the IO controller's to set up: the layout is edited and exported here,
    # not written.
    expect(page.get_by_test_id("pdo-apply-blocked")).to_contain_text("IO controller")
    page.get_by_test_id("pdo-telegram-select").select_option("102")
    expect(page.get_by_test_id("pdo-review")).to_be_disabled()
    expect(page.get_by_test_id("pdo-apply-blocked")).to_contain_text("Not written from here")


def test_a_new_profinet_drive_is_found_named_addressed_and_opened_by_dcp(page: Page) -> None:
    # A LECSN-T twin answering DCP on one end of a veth pair (this test's process); the
    # server searches the other end, gives the drive a name and an address, and opens it
    # there (docs/profinet.md, "DCP").
    from servodesk.domain.profile_loader import ProfileCatalog
    from servodesk.sim.engine import SimulatedDrive
    from servodesk.sim.profinet_device import ProfinetDevice
    from servodesk.sim.veth import create_veth

    with (
        create_veth("sdu") as pair,
        ProfinetDevice(SimulatedDrive(ProfileCatalog().get("lecsn-t"), 1)) as device,
    ):
        device.serve_dcp(pair.slave, manage_addresses=True)
        mac = Path(f"/sys/class/net/{pair.slave}/address").read_text().strip()
        page.goto("/#/connect")
        expect(page.get_by_test_id("dcp-panel")).to_have_count(0)  # CAN: no DCP
        page.get_by_test_id("bus-interface").select_option("profinet")
        page.get_by_test_id("dcp-nic").fill(pair.master)
        page.get_by_test_id("dcp-search").click()
        row = page.get_by_test_id(f"dcp-device-{mac}")
        expect(row.get_by_test_id("dcp-name")).to_have_text("lecsn-t-1")
        expect(row.get_by_test_id("dcp-ip")).to_contain_text("127.0.0.1/255.255.255.0")
        expect(row).to_contain_text("021Ch / 0010h")  # 004 §20.4.4: vendor 540
        expect(row.get_by_test_id("dcp-profile")).to_have_text("profile lecsn-t")

        row.get_by_test_id("dcp-flash").click()
        expect(page.get_by_test_id("notice-info").last).to_contain_text(f"LED of {mac} flashing")
        assert device.station.flashes == 1

        row.get_by_test_id("dcp-edit").click()
        page.get_by_test_id("dcp-edit-name").fill("Press-2")
        expect(page.get_by_test_id("dcp-edit-error")).to_contain_text("lower case only")
        expect(page.get_by_test_id("dcp-edit-set")).to_be_disabled()
        page.get_by_test_id("dcp-edit-name").fill("press-2")
        page.get_by_test_id("dcp-edit-ip").fill("10.79.0.5")
        page.get_by_test_id("dcp-edit-set").click()
        expect(row.get_by_test_id("dcp-name")).to_have_text("press-2")
        expect(row.get_by_test_id("dcp-ip")).to_contain_text("10.79.0.5/255.255.255.0")
        assert device.station.name_of_station == "press-2"

        # The address goes into the form; the twin serves on its own port, not 34964.
        row.get_by_test_id("dcp-use").click()
        expect(page.get_by_test_id("bus-channel")).to_have_value("10.79.0.5")
        page.get_by_test_id("bus-channel").fill(f"10.79.0.5:{device.port}")
        page.get_by_test_id("open-session").click()
        page.wait_for_url(re.compile(r"#/overview/lecsn-t-"))
        sid = page.url.rsplit("/", 1)[1]
        assert device.ars == 1

        # Its Network page reads the name and address back over DCP, as the card's web
        # server shows them; PROFINET has no NMT state to show.
        page.goto(f"/#/network/{sid}")
        expect(page.get_by_test_id("network-nmt")).to_have_text("up (servodesk's supervisor AR)")
        page.get_by_test_id("network-dcp-nic").fill(pair.master)
        page.get_by_test_id("network-dcp-read").click()
        expect(page.get_by_test_id("network-dcp-name")).to_have_text("press-2")
        expect(page.get_by_test_id("network-dcp-ip")).to_have_text("10.79.0.5 (static)")
        page.get_by_test_id("network-dcp-nic").fill("nope0")
        page.get_by_test_id("network-dcp-read").click()
        expect(page.get_by_test_id("network-dcp-failure")).to_contain_text("no network interface")

        # In operation (the session's AR) the drive refuses a new address, and says why.
        page.goto("/#/connect")
        page.get_by_test_id("bus-interface").select_option("profinet")
        page.get_by_test_id("dcp-nic").fill(pair.master)
        page.get_by_test_id("dcp-search").click()
        row.get_by_test_id("dcp-edit").click()
        page.get_by_test_id("dcp-edit-ip").fill("10.79.0.6")
        page.get_by_test_id("dcp-edit-set").click()
        notice = page.get_by_test_id("notice-error")
        expect(notice).to_contain_text("in operation")
        expect(notice).to_contain_text("close servodesk's session")
        notice.get_by_role("button", name="Dismiss").click()
        page.get_by_test_id(f"session-close-{sid}").click()
        expect(page.get_by_test_id(f"session-row-{sid}")).to_have_count(0)

        # Reset to factory, option 8: no name, no address, nothing to open.
        row.get_by_test_id("dcp-reset").click()
        page.get_by_test_id("dcp-reset-mode-8").check()
        page.get_by_test_id("dcp-reset-dialog-confirm").click()
        expect(row.get_by_test_id("dcp-name")).to_have_text("no name")
        expect(row.get_by_test_id("dcp-ip")).to_have_text("no address")
        expect(row.get_by_test_id("dcp-use")).to_be_disabled()
        assert device.station.resets == [8]


def test_an_ethercat_line_is_opened_from_the_connect_page(page: Page) -> None:
    # A HIWIN E twin as slave 1 of a simulated EtherCAT line on one end of a veth pair (this
    # test's process); the server's EtherCAT link (pysoem) opens it on the other end.
    from servodesk.sim.bus import SimulatedBus
    from servodesk.sim.veth import create_veth

    with (
        create_veth("sdb") as pair,
        SimulatedBus.start(drives=[("hiwin-e", 1)], interface="ethercat", channel=pair.slave),
    ):
        page.goto("/#/connect")
        page.get_by_test_id("bus-interface").select_option("ethercat")
        expect(page.get_by_test_id("bus-bitrate")).to_be_disabled()
        page.get_by_test_id("bus-channel").fill(pair.master)
        # Scan finds the line's slave with its identity and profile; Open opens it there.
        page.get_by_test_id("scan-bus").click()
        slave = page.get_by_test_id("scan-node-1")
        expect(slave).to_contain_text("hiwin-e")
        expect(page.get_by_test_id("scan-results")).to_contain_text("Slave")
        slave.get_by_test_id("scan-open-1").click()
        page.wait_for_url(re.compile(r"#/overview/hiwin-e-1"))
        expect(page.locator(".drive-meta")).to_have_attribute(
            "title", f"slave 1 · ethercat · ethercat:{pair.master}"
        )
        page.goto("/#/network/hiwin-e-1")
        expect(page.get_by_test_id("network-link-name")).to_have_text("ethercat")
        expect(page.get_by_test_id("network-nmt")).to_have_text("preop")
        # Cyclic data over EtherCAT: the assigned TxPDO's values live on the PDO page.
        page.goto("/#/pdo/hiwin-e-1")
        expect(page.get_by_test_id("pdo-cyclic-unavailable")).to_have_count(0)
        take_control(page, "hiwin-e-1")  # Starting the cyclic data changes the drive.
        page.get_by_test_id("pdo-cyclic-start").click()
        expect(page.get_by_test_id("pdo-cyclic-state")).to_have_attribute("data-running", "true")
        live = page.get_by_test_id("pdo-live-TxPDO 1A00h-0x6041:00")
        expect(live).to_have_attribute("data-raw", re.compile(r"^\d+$"), timeout=5_000)
        expect(page.get_by_test_id("pdo-cyclic-sync-text")).to_have_text(" · SYNC every 10 ms")
        page.get_by_test_id("pdo-cyclic-stop").click()
        expect(page.get_by_test_id("pdo-cyclic-state")).to_have_attribute("data-running", "false")
        # DC: the drive's SYNC0 from the distributed clocks, at a cycle it takes (HIWIN 000
        # §2.5: 250 µs steps); one it does not take is named before anything is sent.
        page.get_by_test_id("pdo-cyclic-sync").select_option("dc")
        period = page.get_by_test_id("pdo-cyclic-period")
        period.fill("1.1")
        period.press("Tab")
        expect(page.get_by_test_id("pdo-cyclic-cycle-problem")).to_contain_text(
            "0.25 ms steps from 0.25 ms to 4 ms"
        )
        expect(page.get_by_test_id("pdo-cyclic-start")).to_be_disabled()
        period.fill("1.25")
        period.press("Tab")
        expect(page.get_by_test_id("pdo-cyclic-cycle-problem")).to_have_count(0)
        page.get_by_test_id("pdo-cyclic-start").click()
        expect(page.get_by_test_id("pdo-cyclic-sync-text")).to_have_text(
            " · DC SYNC0 every 1.25 ms"
        )
        expect(live).to_have_attribute("data-raw", re.compile(r"^\d+$"), timeout=5_000)
        page.get_by_test_id("pdo-cyclic-stop").click()
        expect(page.get_by_test_id("pdo-cyclic-state")).to_have_attribute("data-running", "false")
        page.goto("/#/connect")
        page.get_by_test_id("session-close-hiwin-e-1").click()
        expect(page.get_by_test_id("session-row-hiwin-e-1")).to_have_count(0)
