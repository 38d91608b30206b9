"""Write the docs' generated pictures into docs/assets/ (``make docs-assets``; never ``make test``).

The dashboard's pages (``dashboard_*.png``) are photographed the same way: ``fuelid online
--virtual`` writes a store (write_back "approve", so a proposal waits), ``fuelid dashboard``
serves it, and headless Chromium (Playwright, given Debian's executable) takes each page.

The demo's HTML report is made the way a user makes it, by the command line: a simulated step
sequence of the reference plant (``fuelid simulate``), then ``fuelid report`` on it. Headless
Chromium takes a screenshot of the top of the page (``report.png``), and the report's own
comparison, Bode and closed-loop figures are copied beside it, so the docs show what the command
writes, never a hand-edited picture. Run from the repository root with fuelid importable:

    .venv/bin/python docs/scripts/assets.py [--out docs/assets]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

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
DASHBOARD_PAGES = {"fleet": "/", "loop": "/loops/{loop}", "window": "/loops/{loop}/windows/{w}"}


def dashboard_screenshots(work: Path, out: Path) -> None:
    """The fleet, loop and window pages of a virtual run's store, as a user sees them."""
    import json
    import urllib.request

    sys.path.insert(0, str(ROOT / "tests"))
    from support.browser import browser_page, dashboard, wait_ready

    config = work / "online.toml"
    config.write_text("[online]\n" + DASHBOARD_ONLINE, encoding="utf-8")
    fuelid(
        "online", "--virtual", "--speed", "50", "--hours", "0.75", "--store", "loop.db",
        "--config", str(config), cwd=work,
    )  # fmt: skip
    with dashboard(work, "--store", str(work / "loop.db")) as (_, base):
        loop = json.loads(urllib.request.urlopen(f"{base}/api/loops").read())["loops"][0]["loop_id"]
        history = json.loads(urllib.request.urlopen(f"{base}/api/loops/{loop}/history").read())
        window = [w for w in history["windows"] if w["accepted"]][-1]["id"]
        with browser_page(1400, 900) as (page, errors):
            for name, path in DASHBOARD_PAGES.items():
                page.goto(base + path.format(loop=loop, w=window))
                wait_ready(page)
                page.wait_for_timeout(1000)
                page.screenshot(path=str(out / f"dashboard_{name}.png"), full_page=True)
        if errors:
            raise SystemExit(f"the dashboard's pages logged errors: {errors}")


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
        fuelid("report", "log.csv", "--out", "report.html", cwd=work)
        screenshot(work / "report.html", args.out / "report.png")
        for key in FIGURES:
            shutil.copyfile(work / f"report_{key}.png", args.out / f"report_{key}.png")
        dashboard_screenshots(work, args.out)
    for path in sorted([*args.out.glob("report*.png"), *args.out.glob("dashboard_*.png")]):
        print(f"wrote {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}")


if __name__ == "__main__":
    main()
