"""The HTML report in a real browser: headless Chromium renders it and every figure loads.

A short simulated log is analysed and written as a report; Chromium then dumps the DOM of a copy
that records, after the load event, each image's natural size (a broken ``data:`` URI loads as
0×0), and takes a screenshot of the page, which must not be blank. Without Chromium the test
skips with the reason, except under CI (the ``CI`` environment variable set), where it fails:
CI must run it (``make test`` installs Chromium when it runs as root).
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from fuelid.htmlreport import FIGURE_KEYS, write_report
from fuelid.io.logs import load_log
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence
from fuelid.units import celsius_to_kelvin
from fuelid.workflow import AnalysisSettings, PlantSource, analyse_log

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
WINDOW = (1280, 5000)
TIMEOUT_S = 120

PROBE = """
<script>
window.addEventListener("load", () => {
  const images = Array.from(document.images).map((img) => ({
    alt: img.alt,
    complete: img.complete,
    width: img.naturalWidth,
    height: img.naturalHeight,
    data_uri: img.src.startsWith("data:image/png;base64,"),
  }));
  const out = document.createElement("pre");
  out.id = "fuelid-probe";
  out.textContent = JSON.stringify(images);
  document.body.appendChild(out);
});
</script>
"""


@pytest.fixture(scope="module")
def browser() -> str:
    """The Chromium executable, found before any report is drawn (the skip is then immediate)."""
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    reason = f"no Chromium on PATH (looked for {', '.join(CHROMIUM_NAMES)})"
    if os.environ.get("CI"):
        pytest.fail(f"{reason}; CI must run the browser test (make test installs it as root)")
    pytest.skip(f"{reason}: install it (apt-get install chromium) to run the browser test")


def _run(browser: str, *args: str) -> subprocess.CompletedProcess[str]:
    command = [
        browser,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--hide-scrollbars",
        "--no-first-run",
        f"--window-size={WINDOW[0]},{WINDOW[1]}",
        *args,
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert done.returncode == 0, f"{' '.join(command)} failed:\n{done.stderr[-2000:]}"
    return done


@pytest.fixture(scope="module")
def report(browser: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("browser")
    config = load_plant_config()
    run = simulate(config, step_sequence([1.0, 2.0, 3.0, 2.0], dwell=20.0), seed=5)
    log = run.to_log().write(folder / "short.csv")
    settings = AnalysisSettings(
        T_range=(celsius_to_kelvin(-20.0), celsius_to_kelvin(50.0)),
        band_width=35.0,
        control_period=1.0,  # never assumed (issue 37)
    )
    analysis = analyse_log(load_log(log), PlantSource(config, "reference_plant.toml"), settings)
    return write_report(analysis, folder / "report.html")[0]


def test_the_report_renders_in_chromium_with_every_figure_loaded(
    browser: str, report: Path, tmp_path: Path
):
    probe = tmp_path / "probe.html"
    probe.write_text(
        report.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8"
    )
    dom = _run(
        browser, "--virtual-time-budget=10000", "--dump-dom", probe.resolve().as_uri()
    ).stdout
    assert re.search(r"<h1>fuelid report: [^<]*short\.csv</h1>", dom), dom[:500]
    found = re.search(r'<pre id="fuelid-probe">(.*?)</pre>', dom, re.DOTALL)
    assert found, "the page's load event never fired (no probe output in the DOM)"
    images = json.loads(html.unescape(found.group(1)))
    assert [img["alt"] for img in images] == list(FIGURE_KEYS)
    for img in images:
        assert img["data_uri"], f"{img['alt']}: not embedded as a data: URI"
        assert img["complete"], f"{img['alt']}: did not finish loading"
        assert img["width"] > 300, f"{img['alt']}: broken image ({img['width']}×{img['height']})"
        assert img["height"] > 200, f"{img['alt']}: broken image ({img['width']}×{img['height']})"

    screenshot = tmp_path / "report.png"
    _run(browser, f"--screenshot={screenshot}", report.resolve().as_uri())
    print(f"screenshot of the report: {screenshot}")
    from PIL import Image

    with Image.open(screenshot) as shot:
        assert shot.size == WINDOW
        pixels = np.asarray(shot.convert("L"), dtype=float)
    # not blank: the page has text and figures, so many pixels are far from the white background
    dark = np.mean(pixels < 200.0)
    assert dark > 0.01, f"the screenshot looks blank ({dark:.2%} non-white pixels)"
    assert pixels.std() > 10.0
