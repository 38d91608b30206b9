"""The noise screen of the AUTO windows: the cheap decision against the full one (issue 26).

The screen (:func:`fuelid.online._pem_screen.noise_screen`) skips pem when its noise pole would be
nearly integrating. Its threshold was tuned on the virtual PLC with seeds 1–2, disturbances
0.1, 0.3, 1.0 L/min, 20 °C, setpoint steps around 40 L/min and the demo's runs; the windows here
are HELD OUT: other seeds, disturbances 0, 0.2 and 0.5 L/min, setpoints around 35 L/min and the
demo's runs of other seeds, fuel at 10 and 30 °C.

Only a skipped pem can disagree (below the threshold pem runs and today's rule decides), so a
disagreement is a window the screen skipped whose pem would have been kept.

Bands, stated before running (:mod:`support.bands`):

- fast test, n = 9 warm windows: if the true disagreement rate is at most 1 %, more than
  ``most_failures(9, 0.01)`` = 2 disagreements happen with probability under 10⁻³;
- slow test, n = 312: the observed count must be at most ``most_failures_under(312)`` = 0, the
  count whose one-sided 95 % Clopper–Pearson upper bound stays under 1 %;
- wherever they disagree, the K kept (oe's) must lie within one standard error of pem's.
"""

from __future__ import annotations

from importlib import resources
from typing import Any

import numpy as np
import pytest

from fuelid.identify import OutputError
from fuelid.online import Online, WindowAnalyser, window_priors
from fuelid.online._pem_screen import closed_loop_choice, noise_screen
from fuelid.plc.virtual import VirtualPLC
from fuelid.profiles.runs import demo_run_profile
from fuelid.store import iodata_from_samples
from support.bands import most_failures
from support.windows import engine_windows, local_setpoints

PLANT = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
HELD_OUT_STEPS = (0.0, 1.5, -2.0, 2.5, 0.5, -1.0, 3.0, -0.5)


def _engine(seed: int, disturbance: float, profile: str, temp_C: float) -> VirtualPLC:
    setpoints = (
        local_setpoints(35.0, HELD_OUT_STEPS) if profile == "steps" else demo_run_profile(seed)
    )
    return VirtualPLC(
        seed=seed, setpoint_profile=setpoints, disturbance_sd_Lpm=disturbance, fuel_temp_C=temp_C
    )


def _study(runs: list[tuple[int, float, str, float]], windows: int) -> list[dict[str, Any]]:
    """Per warm window: the screen's verdict, the full decision, and oe's and pem's K."""
    priors, _ = window_priors(PLANT, control_period=1.0)
    settings: dict[str, Any] = {"order": "auto", "delay": priors.delay, "T_f": priors.flowmeter_T}
    rows = []
    for seed, disturbance, profile, temp_C in runs:
        plc = _engine(seed, disturbance, profile, temp_C)
        last_model, last_noise = None, None
        for i, (samples, _, _) in enumerate(engine_windows(plc, windows + 1, skip_s=60.0)):
            data = iodata_from_samples(samples, 0.02, source="window")
            oe = OutputError(covariance="auto", **settings).fit(data, init=last_model)
            full = closed_loop_choice(data, oe, settings, last_noise, screen=False)
            screen = noise_screen(data.y - oe.y_hat_, data.segment_bounds(), last_noise)
            last_model = oe.model_  # the service warm-starts from the accepted model
            if full.noise is not None:
                last_noise = full.noise
            if i == 0:
                continue  # the cold first window: warm-up
            rows.append(
                {
                    "skip": screen.skip_pem,
                    "pem_kept": full.method == "pem",
                    "K_oe": oe.K_,
                    "K_full": full.estimator.K_,
                    "se_full": full.estimator.stderr_["K"],
                }
            )
    return rows


def _check(rows: list[dict[str, Any]], allowed: int) -> None:
    disagree = [r for r in rows if r["skip"] and r["pem_kept"]]
    skipped = sum(r["skip"] for r in rows)
    kept = sum(r["pem_kept"] for r in rows)
    print(
        f"{len(rows)} windows: pem skipped on {skipped}, kept by the full rule on {kept}; "
        f"disagreements {len(disagree)} (band ≤ {allowed})"
    )
    assert len(disagree) <= allowed, disagree
    for r in disagree:
        assert abs(r["K_oe"] - r["K_full"]) <= r["se_full"], r
    # the screen is worth having: it skips pem on the windows with a drifting disturbance
    assert any(r["skip"] for r in rows)


def test_cheap_decision_agrees_with_the_full_one_on_held_out_windows() -> None:
    runs = [(201, 0.0, "steps", 10.0), (202, 0.2, "runs", 30.0), (203, 0.5, "steps", 30.0)]
    rows = _study(runs, windows=2)
    assert len(rows) == 6
    _check(rows, most_failures(len(rows), 0.01))  # 2


@pytest.mark.slow
@pytest.mark.timeout(900)  # 96 windows, each fitted twice: about 2-3 min on a loaded 2-core box
def test_cheap_decision_agrees_on_96_held_out_windows() -> None:
    """The 24 held-out runs, 4 warm windows each, in the slow set's budget.

    The requirement (agreement on at least 99 % of held-out windows) is measured by
    benchmarks/bench_window.py on 312 held-out windows (and was on 312 more here: 0 and 1
    disagreements, 1 in 624 together); 96 windows cannot bound a rate under 1 % (299 are
    needed with none failing), so this test is the guard against a regression: with the rate
    at the 1 % the requirement allows, more than ``most_failures(96, 0.01)`` = 5 disagreements
    happen with probability at most 0.1 %.
    """
    runs = [
        (seed, disturbance, profile, temp_C)
        for seed in (211, 212)
        for disturbance in (0.0, 0.2, 0.5)
        for profile in ("steps", "runs")
        for temp_C in (10.0, 30.0)
    ]
    rows = _study(runs, windows=4)
    assert len(rows) == 96
    _check(rows, most_failures(len(rows), 0.01))  # 5


def test_screen_reads_a_drift_as_nearly_integrating_and_white_noise_as_not() -> None:
    import scipy.signal

    rng = np.random.default_rng(3)
    e = rng.normal(size=30_000)
    drift = scipy.signal.lfilter(
        [1.0], [1.0, -np.exp(-0.02 / 60.0)], 0.03 * rng.normal(size=e.size)
    )
    bounds = [(0, e.size)]
    # an ARMA(1, 1) start (a drift seen through white meter noise has a zero near its pole)
    assert noise_screen(drift + 0.1 * e, bounds, {"C": [1.0, 0.0], "D": [1.0, 0.0]}).skip_pem
    white = noise_screen(e, bounds, None)
    assert not white.skip_pem
    assert white.pole < 0.5


def _pair(plc: VirtualPLC) -> list[tuple[Any, Any]]:
    """Two warm windows analysed by today's path and the fast one, each warm from its own."""
    priors, k_plant = window_priors(PLANT, control_period=1.0)
    old, new = (
        WindowAnalyser(Online(), priors, 0.02, k_plant=k_plant, ti_s=plc.gains[1], fast=fast)
        for fast in (False, True)
    )
    out = []
    for i, (samples, t_from, t_to) in enumerate(engine_windows(plc, 3, skip_s=60.0)):
        results = [a.analyse(samples, t_from, t_to) for a in (old, new)]
        for a, r in zip((old, new), results, strict=True):
            if r.accepted:
                a.accept(r)
            elif a.last_model_ is None:
                a.resume(r.model)
        if i:
            out.append(tuple(results))
    return out


@pytest.mark.parametrize(
    "make",
    [
        lambda: VirtualPLC(
            seed=301, command_profile=([0, 15, 30, 45, 60], [3.0, 3.2, 2.9, 3.3, 3.0])
        ),
        lambda: VirtualPLC(
            seed=302,
            command_profile=([0, 15, 30, 45, 60], [3.0, 2.8, 3.1, 2.9, 3.0]),
            disturbance_sd_Lpm=0.3,
        ),
        lambda: _engine(303, 0.0, "steps", 20.0),
        lambda: _engine(304, 0.3, "runs", 20.0),
    ],
    ids=["MAN", "MAN-disturbed", "AUTO", "AUTO-disturbed"],
)
def test_fast_path_decides_as_todays_path(make: Any) -> None:
    for old, new in _pair(make()):
        assert new.accepted == old.accepted, (old.reason, new.reason)
        assert new.method == old.method
        assert set(new.to_json()) == set(old.to_json())
        assert (new.model is None) == (old.model is None)
        if old.model is None or new.model is None:
            continue
        for key in ("K", "T", "T2"):
            se = old.stderr.get(key)
            if se is not None:
                assert abs(getattr(new.model, key) - getattr(old.model, key)) <= se, key
