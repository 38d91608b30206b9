"""Write the docs' generated pictures into docs/assets/ (``make docs-assets``; never ``make test``).

The dashboard's pages (``dashboard_*.png``) are photographed the same way, live: ``fuelid online
--virtual`` runs (write_back "approve", so proposals wait), ``fuelid dashboard`` serves its store,
and headless Chromium (Playwright, given Debian's executable) follows the loop page as an engineer
through every state an operator meets: a proposal waiting, the trend showing a stored range (not
following), the confirmation, the write verified, a revert, the dashboard killed (kill -9) and
started again on the same port, the service killed; a second browser takes the fleet, a window
and the 404 page. A second run, a virtual PLC in this process whose link is dropped, photographs
a proposal gone out of date and the link down, then back with the outage on the trend and in the
events.

The demo's HTML report is made the way a user makes it, by the command line: a simulated step
sequence of the reference plant (``fuelid simulate``), then ``fuelid report`` on it. Headless
Chromium takes a screenshot of the top of the page (``report.png``), and the report's own
comparison, Bode and closed-loop figures are copied beside it, so the docs show what the command
writes, never a hand-edited picture. Run from the repository root with fuelid importable:

    .venv/bin/python docs/scripts/assets.py [--out docs/assets]
"""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
#: the top of the report (the plant, the notices, the gains and margins) at a laptop's width
WINDOW = "1280,1600"
FIGURES = ("comparison", "bode", "closed_loop")


def fuelid(*args: str, cwd: Path) -> None:
    """Run one fuelid command as a user would, failing loudly with its output."""
    command = [sys.executable, "-m", "fuelid", *args]
    print("$ fuelid " + " ".join(args), flush=True)
    subprocess.run(command, cwd=cwd, check=True)


def chromium() -> str:
    """The browser (``make browser`` installs it when missing, as root)."""
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    raise SystemExit("chromium not found: run `make browser` (as root) or install it")


def screenshot(page: Path, png: Path) -> None:
    """A screenshot of ``page`` by headless Chromium (no GPU, no sandbox: containers, CI)."""
    with tempfile.TemporaryDirectory() as profile:  # no state from a user's own profile
        subprocess.run(
            [
                chromium(),
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                f"--user-data-dir={profile}",
                f"--window-size={WINDOW}",
                f"--screenshot={png}",
                page.as_uri(),
            ],
            check=True,
            capture_output=True,
            timeout=120,
        )
    if not png.exists() or png.stat().st_size == 0:
        raise SystemExit(f"chromium wrote no screenshot to {png}")


DASHBOARD_ONLINE = 'identify_every_s = 120\nwindow_s = 240\nwrite_back = "approve"\n'
#: the live virtual loop photographed: at most 2 h of plant time at 20x, 6 min of wall time (the
#: service is killed before: about 3 min)
DASHBOARD_RUN = ("--speed", "20", "--hours", "2")
DASHBOARD_VIEWPORT = (1400, 900)
PROPOSAL_WAIT_S = 120.0
"""Wall time a waiting proposal may take to appear on the loop page [s]."""
WRITTEN_WAIT_S = 60.0
"""Wall time an approved proposal may take to be written and verified [s]."""
STOP_WAIT_S = 30.0
"""Wall time the page may take to say the service, then the dashboard, stopped [s]."""
LOOP_WINDOWS = 8
"""Windows judged before the loop page is photographed: its model history has a history."""
APPROVE_ATTEMPTS = 4
"""Proposals tried: one superseded by a newer window before its write is tried again."""
LINK_ONLINE = 'identify_every_s = 60\nwindow_s = 120\nwrite_back = "approve"\n'
"""The link run's [online] table: short windows, so that a proposal goes out of date soon (its
window older than 6 window lengths while the newer ones say the same)."""
LINK_SPEED = 40.0
"""The link run's speed-up: a proposal out of date within about 30 s of wall time."""
OUT_OF_DATE_WAIT_S = 150.0
"""Wall time a proposal may take to appear and go out of date in the link run [s]."""
KILLED_MID_ANSWER = ("ERR_EMPTY_RESPONSE",)
"""A request the dashboard was answering when it was killed: expected then, as the stream's
retries (``support.browser.NETWORK_FAILURES``)."""
_CARD_STATE = (
    '(() => {{ const c = document.querySelector("#proposals-part div.proposal'
    "[data-proposal='{0}']\"); return c ? c.dataset.state : 'absent'; }})()"
)
_WAITING_CARD = (
    "(() => { const c = document.querySelector("
    "'#proposals-part div.proposal[data-state=waiting]'); return c ? c.dataset.proposal : ''; })()"
)


def _wait(page: Any, expression: str, what: str, timeout: float) -> Any:
    """``expression`` once truthy on ``page``; a clear error naming ``what`` past ``timeout`` s."""
    from support.browser import wait_until

    try:
        return wait_until(page, expression, timeout)
    except AssertionError as error:
        raise SystemExit(f"dashboard screenshots: {what}: not within {timeout:.0f} s") from error


def _clip_top(page: Any, until: str, png: Path) -> None:
    """The top of ``page`` down to the bottom of the element ``until`` (a state, not a page)."""
    page.evaluate("window.scrollTo(0, 0)")
    bottom = page.evaluate(f"document.querySelector({until!r}).getBoundingClientRect().bottom")
    width = page.viewport_size["width"]
    page.screenshot(path=str(png), clip={"x": 0, "y": 0, "width": width, "height": bottom + 12})


def _login(page: Any, base: str, token: str, path: str) -> None:
    """Log in as the engineer "eve" at /login, landing on ``path``."""
    page.goto(f"{base}/login?next={path}")
    page.fill("input[name=name]", "eve")
    page.fill("input[name=token]", token)
    page.click("button[type=submit]")
    page.wait_for_url(f"{base}{path}")


def _shoot_loop(page: Any, out: Path) -> None:
    """The loop page following live with a proposal waiting, its analysis charts drawn."""
    _wait(
        page,
        f"document.querySelectorAll('#windows tr[data-window]').length >= {LOOP_WINDOWS}",
        f"{LOOP_WINDOWS} windows on the loop page",
        PROPOSAL_WAIT_S,
    )
    _wait(page, _WAITING_CARD, "a waiting proposal on the loop page", PROPOSAL_WAIT_S)
    _wait(page, "document.getElementById('trend').dataset.newest", "the live trend", 30)
    page.locator("#analysis").scroll_into_view_if_needed()
    _wait(page, "document.getElementById('analysis').dataset.drawn", "the analysis charts", 60)
    page.evaluate("window.scrollTo(0, 0)")
    page.wait_for_timeout(1000)
    if page.evaluate("document.getElementById('trend').dataset.following") != "1":
        raise SystemExit("dashboard screenshots: the loop page's trend stopped following")
    page.screenshot(path=str(out / "dashboard_loop.png"), full_page=True)


def _shoot_fleet_and_window(page: Any, base: str, loop: str, out: Path) -> None:
    """The fleet page and the page of the newest accepted window (a second browser)."""
    from support.browser import wait_ready

    history = json.loads(urllib.request.urlopen(f"{base}/api/loops/{loop}/history").read())
    window = [w for w in history["windows"] if w["accepted"]][-1]["id"]
    page.goto(f"{base}/")
    wait_ready(page)
    page.wait_for_timeout(1000)
    _clip_top(page, "footer", out / "dashboard_fleet.png")  # one loop: not the empty screen
    page.goto(f"{base}/loops/{loop}/windows/{window}")
    wait_ready(page)
    page.wait_for_timeout(1000)
    page.screenshot(path=str(out / "dashboard_window.png"), full_page=True)


def _shoot_not_following(page: Any, out: Path) -> None:
    """The trend after "1 h": a stored range, "follow live" offered; then following again."""
    page.click("button[data-range-minutes='60']")
    _wait(
        page,
        "document.getElementById('trend').dataset.following === '0'"
        " && !document.getElementById('live').hidden"
        " && document.getElementById('trend-source').textContent.includes('thinned')",
        "the trend showing a stored range",
        30,
    )
    page.wait_for_timeout(500)
    page.locator("section:has(#trend)").screenshot(path=str(out / "dashboard_not_following.png"))
    page.click("#live")
    _wait(page, "document.getElementById('trend').dataset.following === '1'", "following", 10)


def _shoot_not_found(page: Any, base: str, out: Path) -> None:
    """The HTML 404 of a page route (an unknown loop)."""
    response = page.goto(f"{base}/loops/no-such-loop")
    if response is None or response.status != 404:
        raise SystemExit(f"dashboard screenshots: /loops/no-such-loop answered {response}")
    page.wait_for_timeout(500)
    _clip_top(page, "footer", out / "dashboard_not_found.png")


def _approve_one(page: Any, out: Path) -> bool:
    """Approve the waiting proposal (a reason, its confirmation photographed) and wait for it.

    True when it was written and verified, False when it went another way before its write
    (superseded by a newer window's proposal).
    """
    proposal = _wait(page, _WAITING_CARD, "a waiting proposal", PROPOSAL_WAIT_S)
    form = f"form.action[data-proposal='{proposal}']"
    card = f"#proposals-part div.proposal[data-proposal='{proposal}']"
    new_kc = page.locator(f"{card} table.kv tr:first-child td b").inner_text()
    page.fill(f"{form} input[name=why]", "the newest windows agree; the loop is calm")
    page.click(f"{form} button[data-kind=approve]")
    page.locator(f"{form} .confirm").wait_for(state="visible", timeout=5000)
    page.locator("#proposals-part").screenshot(path=str(out / "dashboard_proposal_confirm.png"))
    page.click(f"{form} .confirm button.yes", timeout=5000)
    deadline = time.monotonic() + WRITTEN_WAIT_S
    while time.monotonic() < deadline:
        state = page.evaluate(_CARD_STATE.format(proposal))
        if state == "written":  # and the gains in force are the ones the PLC echoed
            _wait(
                page,
                "document.getElementById('gains-in-force').textContent"
                f".startsWith('Gains in force: Kc {new_kc} ')",
                f"the gains of proposal #{proposal} in force",
                WRITTEN_WAIT_S,
            )
            page.locator("#proposals-part").screenshot(
                path=str(out / "dashboard_proposal_written.png")
            )
            return True
        if state not in ("waiting", "approved", "writing"):
            print(f"proposal #{proposal}: {state} before its write; the next one", flush=True)
            return False
        page.wait_for_timeout(300)
    raise SystemExit(
        f"dashboard screenshots: proposal #{proposal} not written within {WRITTEN_WAIT_S:.0f} s"
    )


def _shoot_approval(page: Any, out: Path) -> None:
    """A proposal's confirmation, then its card written and verified with the gains in force."""
    for _ in range(APPROVE_ATTEMPTS):
        if _approve_one(page, out):
            return
    raise SystemExit(f"dashboard screenshots: {APPROVE_ATTEMPTS} proposals superseded unwritten")


def _shoot_reverted(page: Any, out: Path) -> None:
    """A revert asked for (a reason, confirmed): the card reverted, the old gains in force."""
    page.fill("form.revert input[name=why]", "the loop rings more than before")
    page.click("form.revert button[data-kind=revert]")
    page.locator("form.revert .confirm").wait_for(state="visible", timeout=5000)
    page.click("form.revert .confirm button.yes", timeout=5000)
    _wait(
        page,
        "document.querySelector('#proposals-part div.proposal[data-state=reverted]') !== null"
        " && !document.getElementById('gains-in-force').textContent.includes('do not show yet')",
        "a reverted card",
        WRITTEN_WAIT_S,
    )
    page.wait_for_timeout(500)
    page.locator("#proposals-part").screenshot(path=str(out / "dashboard_proposal_reverted.png"))


def _shoot_reconnected(page: Any, out: Path) -> None:
    """The dashboard started again: the banner says "reconnected at …", nothing greyed."""
    _wait(page, "document.body.dataset.connection === 'reconnected'", "reconnected", STOP_WAIT_S)
    page.wait_for_timeout(500)
    if page.evaluate("document.body.classList.contains('stale')"):
        raise SystemExit("dashboard screenshots: the page stayed greyed after reconnecting")
    _clip_top(page, "#proposals-part", out / "dashboard_reconnected.png")


def _shoot_service_stopped(page: Any, service: Any, out: Path) -> None:
    """After ``kill -9`` of the service: its chip red, the live chips grey "unknown since …"."""
    from fuelid.dashboard._fleet import LIVE_CHIPS
    from support.browser import page_chips

    if service.proc.poll() is not None:
        raise SystemExit("dashboard screenshots: the virtual run ended before its kill")
    service.stop(signal.SIGKILL)
    deadline = time.monotonic() + STOP_WAIT_S
    while True:
        chips = page_chips(page)
        live = [chips.get(name, ("", ""))[1] for name in LIVE_CHIPS]
        if chips.get("service", ("", ""))[0] == "alarm" and all(
            text.startswith("unknown since the stop") for text in live
        ):
            break
        if time.monotonic() > deadline:
            raise SystemExit(f"dashboard screenshots: the page did not say the stop: {chips}")
        page.wait_for_timeout(500)
    _clip_top(page, "#link", out / "dashboard_service_stopped.png")


def _shoot_disconnected(page: Any, board: Any, errors: list[str], out: Path) -> None:
    """After killing the dashboard: the banner, the page greyed. Only network errors then."""
    from support.browser import NETWORK_FAILURES

    page.evaluate("1")  # the console events so far are in
    before = list(errors)
    board.stop(signal.SIGKILL)
    _wait(page, "document.body.dataset.connection === 'disconnected'", "disconnected", STOP_WAIT_S)
    page.wait_for_timeout(500)
    _clip_top(page, "#proposals-part", out / "dashboard_disconnected.png")
    if before:
        raise SystemExit(f"the dashboard's pages logged errors: {before}")
    expected = (*NETWORK_FAILURES, *KILLED_MID_ANSWER)
    print(f"after the dashboard's kill the pages logged: {errors[len(before) :]}", flush=True)
    after = [e for e in errors[len(before) :] if not any(n in e for n in expected)]
    if after:
        raise SystemExit(f"the loop page logged errors after the dashboard's kill: {after}")


def dashboard_screenshots(work: Path, out: Path) -> None:
    """Every state of the pages an operator meets, from a live virtual loop.

    ``fuelid online --virtual`` runs (write_back "approve") beside ``fuelid dashboard``; an
    engineer's page follows the loop through a waiting proposal, its approval and write, the
    service's kill -9 and the dashboard's; a second browser photographs the fleet and a window.
    """
    sys.path.insert(0, str(ROOT / "tests"))
    from fuelid.dashboard._users import UsersFile
    from support.browser import browser_pages, dashboard, port_of, virtual_service, wait_ready

    users = UsersFile(work / "users.json")
    token = users.add("eve", "engineer")
    config = work / "online.toml"
    config.write_text("[online]\n" + DASHBOARD_ONLINE, encoding="utf-8")
    store = work / "loop.db"
    print(f"$ fuelid online --virtual {' '.join(DASHBOARD_RUN)} (and fuelid dashboard)", flush=True)
    with virtual_service(work, store, *DASHBOARD_RUN, "--config", str(config)) as service:
        service.wait_for(lambda line: "link up" in line)
        with dashboard(work, "--store", str(store), "--users", str(users.path)) as (board, base):
            loops = json.loads(urllib.request.urlopen(f"{base}/api/loops").read())["loops"]
            loop = loops[0]["loop_id"]
            with browser_pages(2, *DASHBOARD_VIEWPORT) as ((page, other), errors):
                _login(page, base, token, f"/loops/{loop}")
                wait_ready(page)
                _shoot_loop(page, out)
                _shoot_not_following(page, out)
                _shoot_fleet_and_window(other, base, loop, out)
                _shoot_approval(page, out)
                _shoot_reverted(page, out)
                _shoot_disconnected(page, board, errors, out)
                again = ("--store", str(store), "--users", str(users.path))
                with dashboard(work, *again, port=port_of(base)):
                    _shoot_reconnected(page, out)
                    _login(page, base, token, f"/loops/{loop}")  # its sessions died with it
                    wait_ready(page)
                    _shoot_service_stopped(page, service, out)
                    _shoot_not_found(other, base, out)  # its console error: after the checks


def _shoot_out_of_date(page: Any, out: Path) -> None:
    """A proposal left waiting until its window is too old to write: "out of date"."""
    _wait(
        page,
        "document.querySelector('#proposals-part div.proposal[data-state=out_of_date]')",
        "an out-of-date proposal",
        OUT_OF_DATE_WAIT_S,
    )
    page.wait_for_timeout(500)
    page.locator("#proposals-part").screenshot(path=str(out / "dashboard_proposal_out_of_date.png"))


def _shoot_link(page: Any, virtual: Any, out: Path) -> None:
    """The PLC's link dropped (the page says it), then back: the outage on the trend and events."""
    virtual.stop_link()
    try:
        _wait(
            page,
            "['down', 'link_down'].includes(document.body.dataset.service)",
            "the link down",
            STOP_WAIT_S,
        )
        page.wait_for_timeout(500)
        _clip_top(page, "#link", out / "dashboard_link_down.png")
    finally:
        virtual.start_link()
    _wait(
        page,
        "document.querySelector('#events').textContent.includes('without a link')",
        "the link back in the events",
        STOP_WAIT_S,
    )
    page.wait_for_timeout(1500)
    page.locator("section:has(#trend)").screenshot(path=str(out / "dashboard_link_gap.png"))
    # the events' heading and table (the part is as tall as the windows beside it)
    top = page.locator("#events-part h2").bounding_box()
    table = page.locator("#events").bounding_box()
    if top is None or table is None:
        raise SystemExit("dashboard screenshots: no events table on the loop page")
    left = min(top["x"], table["x"]) - 8
    scrolled = float(page.evaluate("window.scrollY"))  # the boxes are the viewport's
    page.screenshot(
        path=str(out / "dashboard_link_events.png"),
        full_page=True,
        clip={
            "x": left,
            "y": top["y"] + scrolled - 8,
            "width": table["x"] + table["width"] - left + 8,
            "height": table["y"] + table["height"] - top["y"] + 16,
        },
    )


def link_screenshots(work: Path, out: Path) -> None:
    """A proposal out of date and the PLC's link dropped, from a second live run.

    The virtual PLC runs in this process (its link can be dropped), ``fuelid online --config``
    on it (write_back "approve", short windows) and ``fuelid dashboard`` on its store.
    """
    from importlib import resources

    from fuelid.plc.virtual import VirtualPlcThread
    from support.browser import Process, browser_page, dashboard, wait_ready

    plant = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
    store = work / "link.db"
    site = work / "link-site.toml"
    # the service beats once a wall second: many of the PLC's heartbeat timeouts at 40x
    with VirtualPlcThread(
        speed=LINK_SPEED, setpoint_profile="run", heartbeat_timeout_s=1e6
    ) as virtual:
        text = virtual.site_text(store_url=f"sqlite:///{store}", plant=plant)
        site.write_text(text + "\n[online]\n" + LINK_ONLINE, encoding="utf-8")
        print(
            f"$ fuelid online --config {site.name} (a virtual PLC at {LINK_SPEED:g}x)", flush=True
        )
        service = Process(["online", "--config", str(site)], work)
        try:
            service.wait_for(lambda line: "link up" in line)
            with dashboard(work, "--store", str(store)) as (_, base):
                loops = json.loads(urllib.request.urlopen(f"{base}/api/loops").read())["loops"]
                with browser_page(*DASHBOARD_VIEWPORT) as (page, errors):
                    page.goto(f"{base}/loops/{loops[0]['loop_id']}")
                    wait_ready(page)
                    _shoot_out_of_date(page, out)
                    _shoot_link(page, virtual, out)
                    if errors:
                        raise SystemExit(f"the link run's page logged errors: {errors}")
        finally:
            service.stop(signal.SIGINT)


def main() -> None:
    """Simulate, report, screenshot: every picture of docs/assets/ from the command line."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "assets")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        fuelid(
            "simulate", "log.csv", "--profile", "steps", "--levels", "2,3,2.5,3.5,3",
            "--dwell", "30", "--seed", "7", "--fuel-temp", "15", "--quiet", cwd=work,
        )  # fmt: skip
        # the PLC's PI period: the simulation's (``fuelid simulate --control-period``, 1 s)
        fuelid("report", "log.csv", "--control-period", "1", "--out", "report.html", cwd=work)
        screenshot(work / "report.html", args.out / "report.png")
        for key in FIGURES:
            shutil.copyfile(work / f"report_{key}.png", args.out / f"report_{key}.png")
        dashboard_screenshots(work, args.out)
        link_screenshots(work, args.out)
    for path in sorted([*args.out.glob("report*.png"), *args.out.glob("dashboard_*.png")]):
        print(f"wrote {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}")


if __name__ == "__main__":
    main()
