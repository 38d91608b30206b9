"""Issue 38 item 7: temperatures and intervals printed with the digits their precision supports.

An interval is printed with its width to two significant digits: each end is then rounded to
at most half a unit of the width's second digit, so the printed width is within one such unit
(≤ 10 % of the width) of the true one, and two ends that differ never print alike. A fuel
temperature (the mean of a sensor reading) is printed to 0.1 °C.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuelid.cli._common import format_interval
from fuelid.htmlreport import report_figures
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model
from fuelid.plant import load_plant_config
from fuelid.units import celsius_to_kelvin, format_celsius
from fuelid.workflow import AnalysisSettings, PlantSource, analyse_log


def _ends(text: str) -> tuple[float, float]:
    low, high = text.split(" … ")
    return float(low), float(high)


def test_the_issue_interval_shows_distinct_ends() -> None:
    estimate, se = 21.0004, 0.0002
    low, high = estimate - 1.96 * se, estimate + 1.96 * se
    text = format_interval(low, high, minimum=5)
    printed_low, printed_high = _ends(text)
    assert printed_low != printed_high, text
    assert abs((printed_high - printed_low) - (high - low)) <= 0.1 * (high - low), text


@pytest.mark.parametrize("seed", range(5))
def test_any_interval_keeps_its_width_to_two_digits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(200):
        centre = float(rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-3, 5))
        width = abs(centre) * 10 ** rng.uniform(-9, 0)
        text = format_interval(centre - width / 2, centre + width / 2)
        printed_low, printed_high = _ends(text)
        assert abs((printed_high - printed_low) - width) <= 0.1 * width, text


def test_a_fuel_temperature_is_printed_to_a_tenth_of_a_degree() -> None:
    assert format_celsius(celsius_to_kelvin(12.9985)) == "13"
    assert format_celsius(celsius_to_kelvin(12.96)) == "13"
    assert format_celsius(celsius_to_kelvin(12.94)) == "12.9"
    assert format_celsius(celsius_to_kelvin(-20.0)) == "-20"


def test_the_report_overview_names_the_log_temperature_to_a_tenth_of_a_degree() -> None:
    h = 0.1
    u = np.repeat([1.0, 1.5, 2.0, 1.5, 1.0], 300)
    rng = np.random.default_rng(5)
    y = 14.0 + simulate_model(ProcessModel(K=14.0, T=1.5, delay=0.3), u, h)
    y += rng.normal(0.0, 0.02, u.size)
    # a sensor reading 12.9985 °C on average (its mean, as the report takes it)
    temperature = celsius_to_kelvin(12.9985) + np.zeros(u.size)
    data = IOData(u, y, h, T_fuel=temperature)
    analysis = analyse_log(
        data, PlantSource(load_plant_config(), None), AnalysisSettings(control_period=1.0)
    )
    title = report_figures(analysis)["overview"][0].texts[0].get_text()
    assert "fuel at 13 °C" in title, title
    assert not math.isnan(analysis.T_fuel)
