"""Users in the browser (issue 45, docs/security.md "Users"): on a server with accounts the UI
shows a login page; a user logs in, takes control, jogs and logs out; another user is refused
control while the first holds it (and may not force-take it); an administrator ends the first
user's session on the Users page, and the motion it held stops at once."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, expect

from tests.browser.harness import HarnessError, running_server, take_control
from tests.security.server import PASSWORD, make_accounts

pytestmark = pytest.mark.browser

SID = "cia402-generic-1"


@pytest.fixture(scope="module")
def login_server() -> Iterator[str]:
    data = Path(tempfile.mkdtemp(prefix="servodesk-login-"))
    make_accounts(data, {"eve": "engineer", "sam": "service", "admin": "administrator"})
    env = {
        "SERVODESK_DATA_DIR": str(data),
        "SERVODESK_SIM_PROFILES": "cia402-generic",
        "SERVODESK_SIM_CHANNEL": f"login-{os.getpid()}",
    }
    try:
        with running_server(env=env) as base:
            yield base
    except HarnessError as e:
        pytest.fail(str(e), pytrace=False)


@contextmanager
def person(browser: Browser, base: str) -> Iterator[Page]:
    """One person's browser (cookies and sessionStorage of its own)."""
    ctx = browser.new_context(base_url=base, viewport={"width": 1440, "height": 960})
    ctx.set_default_timeout(10_000)
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        yield pg
    finally:
        ctx.close()
    assert not errors, f"uncaught errors in the page: {errors}"


def log_in(page: Page, user: str, password: str = PASSWORD) -> None:
    page.goto("/")
    expect(page.get_by_test_id("login-page")).to_be_visible()
    page.get_by_test_id("login-user").fill(user)
    page.get_by_test_id("login-password").fill(password)
    page.get_by_test_id("login-submit").click()
    expect(page.get_by_test_id("user-menu")).to_have_attribute("data-user", user)


def open_operation(page: Page) -> None:
    page.goto(f"/#/operation/{SID}")
    expect(page.get_by_test_id("operation-page")).to_be_visible()
    expect(page.get_by_test_id("socket-banner")).to_have_count(0, timeout=10_000)
    expect(page.get_by_test_id("control-indicator")).to_have_attribute("data-known", "true")


def enable(page: Page) -> None:
    state = page.get_by_test_id("op-state")
    expect(state).not_to_have_text("—")
    if state.inner_text().strip() != "Operation enabled":
        page.get_by_test_id("servo-on").click()
    expect(state).to_have_text("Operation enabled", timeout=10_000)


def wait_nobody_holds(page: Page) -> None:
    expect(page.get_by_test_id("control-indicator")).to_have_attribute(
        "data-owner", "", timeout=10_000
    )


def test_log_in_take_control_jog_and_log_out(browser: Browser, login_server: str) -> None:
    with person(browser, login_server) as page:
        page.goto("/")
        expect(page.get_by_test_id("login-page")).to_be_visible()
        page.get_by_test_id("login-user").fill("eve")
        page.get_by_test_id("login-password").fill("not her password")
        page.get_by_test_id("login-submit").click()
        expect(page.get_by_test_id("login-error")).to_contain_text("wrong user name or password")

        log_in(page, "eve")
        expect(page.get_by_test_id("user-role")).to_have_text("engineer")
        open_operation(page)
        wait_nobody_holds(page)
        take_control(page)
        enable(page)
        jog = page.get_by_test_id("jog-plus")
        jog.hover()
        page.mouse.down()
        expect(page.get_by_test_id("motion-status")).to_have_attribute("data-active", "true")
        page.wait_for_timeout(500)
        page.mouse.up()
        expect(page.get_by_test_id("op-velocity")).to_have_text("0", timeout=2_000)
        page.get_by_test_id("servo-off").click()
        page.get_by_test_id("control-release").click()
        expect(page.get_by_test_id("control-indicator")).to_have_attribute("data-owner", "")

        page.get_by_test_id("logout").click()
        expect(page.get_by_test_id("login-page")).to_be_visible()
        page.reload()  # The session is gone on the server, not only in this page.
        expect(page.get_by_test_id("login-page")).to_be_visible()


def test_another_user_is_refused_and_an_administrator_ends_the_session(
    browser: Browser, login_server: str
) -> None:
    with (
        person(browser, login_server) as eve,
        person(browser, login_server) as sam,
        person(browser, login_server) as admin,
    ):
        log_in(eve, "eve")
        open_operation(eve)
        wait_nobody_holds(eve)
        take_control(eve)
        enable(eve)
        eve.get_by_test_id("jog-plus").hover()
        eve.mouse.down()  # Held: eve's tab sends the dead-man's heartbeats.
        expect(eve.get_by_test_id("motion-status")).to_have_attribute("data-active", "true")

        # sam sees eve by name; he may not take control nor force-take it from another user.
        log_in(sam, "sam")
        open_operation(sam)
        indicator = sam.get_by_test_id("control-indicator")
        expect(indicator).to_have_attribute("data-user", "eve")
        expect(sam.get_by_test_id("control-holder")).to_have_text("eve")
        expect(sam.get_by_test_id("control-take")).to_have_count(0)
        force = sam.get_by_test_id("control-force")
        expect(force).to_be_disabled()
        expect(force).to_have_attribute(
            "title", 'your role (service) lacks the right "force_control"; ask an administrator'
        )
        r = sam.request.post(
            f"/api/v1/sessions/{SID}/control",
            data='{"action": "take"}',
            headers={"Content-Type": "application/json", "X-Servodesk-Client": "sam-script"},
        )
        assert r.status == 409 and "'eve'" in r.json()["message"]
        assert int(sam.get_by_test_id("op-velocity").inner_text()) > 0  # Still jogging.

        # The administrator ends eve's session on the Users page: the jog stops at once.
        log_in(admin, "admin")
        admin.goto("/#/users")
        end = admin.get_by_test_id("end-session-eve")
        expect(end).to_be_visible()
        end.click()
        expect(sam.get_by_test_id("op-velocity")).to_have_text("0", timeout=2_000)
        expect(sam.get_by_test_id("op-state")).not_to_have_text("Operation enabled")
        expect(eve.get_by_test_id("login-page")).to_be_visible()
        eve.mouse.up()


def test_a_tab_left_without_input_is_locked_although_it_polls(browser: Browser) -> None:
    """CR 2.5 session lock: the server ends a session after its idle time without an HTTP
    request, but an open tab polls and would keep it for ever. The UI counts the person's
    input instead: without any, the tab logs out after the idle time and says why, while its
    own requests went on the whole time."""
    data = Path(tempfile.mkdtemp(prefix="servodesk-idle-"))
    make_accounts(data, {"eve": "engineer"})
    env = {
        "SERVODESK_DATA_DIR": str(data),
        "SERVODESK_SIM_PROFILES": "cia402-generic",
        "SERVODESK_SIM_CHANNEL": f"idle-{os.getpid()}",
        "SERVODESK_SESSION_IDLE_S": "4",
    }
    try:
        with running_server(env=env) as base, person(browser, base) as page:
            log_in(page, "eve")
            # A page's polling, without input: every 0.5 s an HTTP request of this session.
            page.evaluate(
                "setInterval(() => fetch('/api/v1/health', {credentials: 'same-origin'}), 500)"
            )
            expect(page.get_by_test_id("login-page")).to_be_visible(timeout=10_000)
            expect(page.get_by_test_id("login-reason")).to_contain_text("without input")
            r = page.request.get(f"{base}/api/v1/auth/me")
            assert r.status == 401  # The session really ended on the server.
    except HarnessError as e:
        pytest.fail(str(e), pytrace=False)
