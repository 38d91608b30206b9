"""What the numbers rest on: signal check, plant-gain comparison, priors, operating point.

Issue 12 items 1, 2 and 7: a command left in mA gave gains 4× too high without a word; the
report assumed the reference meter silently; the operating point was dropped between commands.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.identify import IdentifyOptions
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel
from fuelid.plant import linearise, load_plant_config
from fuelid.units import celsius_to_kelvin
from fuelid.workflow import OperatingPoint, PlantSource, check_signals, gain_unit
from fuelid.workflow._assumptions import PLANT_GAIN_BOUND, check_gain_against_plant, resolve_priors

CONFIG = load_plant_config()
REFERENCE = PlantSource(CONFIG)
USERS = PlantSource(CONFIG, "plant.toml")
T20 = celsius_to_kelvin(20.0)


def record(u: np.ndarray, y: np.ndarray, u_unit: str = "V", y_unit: str = "L/min") -> IOData:
    return IOData(u=u, y=y, sample_time=0.02, u_unit=u_unit, y_unit=y_unit)


STEPS = np.repeat([2.0, 2.5, 3.0, 2.5], 50)
FLOW = 14.0 * STEPS


def test_signals_in_the_units_of_the_gains_pass():
    assert check_signals(record(STEPS, FLOW), REFERENCE) == []
    assert check_signals(record(STEPS, FLOW), USERS) == []
    assert check_signals(record(STEPS, FLOW, "", ""), REFERENCE) == []  # units unknown, in range


def test_a_command_in_milliamps_is_named_by_its_unit_and_by_its_range():
    current = 4.0 + (STEPS - 1.0) * 4.0  # the same command as a 4–20 mA loop current
    (by_unit,) = check_signals(record(current, FLOW, "mA"), REFERENCE)
    assert "in mA" in by_unit
    assert "--input-scale 4:20:1:5" in by_unit
    (by_range,) = check_signals(record(current, FLOW, ""), REFERENCE)
    assert "4–20 mA" in by_range
    assert "--input-scale 4:20:1:5" in by_range


@pytest.mark.parametrize(
    ("command", "cause"),
    [
        ((STEPS - 1.0) / 4.0 * 27648.0, "counts"),
        ((STEPS - 1.0) / 4.0 * 100.0, "percent"),
        (STEPS + 3.0, "unscaled input or a different drive"),
    ],
)
def test_a_command_outside_the_drive_range_names_its_likely_cause(command, cause):
    (finding,) = check_signals(record(command, FLOW, ""), REFERENCE)
    assert "1…5 V" in finding
    assert cause in finding


def test_a_command_just_beyond_the_range_is_a_calibration_offset_not_a_mistake():
    assert check_signals(record(STEPS * 0.0 + np.linspace(0.9, 5.1, STEPS.size), FLOW), USERS) == []


def test_the_flow_is_checked_against_a_users_meter_span_only():
    span = CONFIG.flowmeter.span_Lpm
    big = np.linspace(0.5, 1.5, STEPS.size) * span  # reaches 150 % of the span
    assert check_signals(record(STEPS, big), REFERENCE) == []  # another loop may be bigger
    (finding,) = check_signals(record(STEPS, big), USERS)
    assert "beyond the meter span" in finding
    counts = FLOW / span * 27648.0
    assert "counts" in check_signals(record(STEPS, counts), REFERENCE)[0]


def test_the_identified_gain_is_compared_with_a_users_plant_only():
    u = 3.0
    predicted = linearise(CONFIG, u, T20).static_gain
    point = OperatingPoint(u=u, y=40.0, T_fuel=T20, T_fuel_source="log")
    low, high = PLANT_GAIN_BOUND
    for ratio in (low * 1.01, 1.0, high * 0.99):
        model = ProcessModel(K=ratio * predicted, T=1.0)
        assert check_gain_against_plant(model, USERS, point, T20) is None
    four_times = ProcessModel(K=4.0 * predicted, T=1.0)  # the mA mistake: 16 mA over 4 V
    finding = check_gain_against_plant(four_times, USERS, point, T20)
    assert finding is not None
    assert "4.00×" in finding
    assert check_gain_against_plant(four_times, REFERENCE, point, T20) is None


def test_priors_come_only_from_a_users_plant_file():
    options, sources = resolve_priors(IdentifyOptions(), REFERENCE, T20)
    assert options.flowmeter_T is None
    assert options.flowmeter_delay is None
    assert sources == {"flowmeter_T": "not given", "flowmeter_delay": "not given"}
    options, sources = resolve_priors(IdentifyOptions(flowmeter_T=0.7), USERS, T20)
    assert options.flowmeter_T == 0.7  # an option wins over the plant file
    assert options.flowmeter_delay == CONFIG.flowmeter.delay_s
    assert sources == {"flowmeter_T": "option", "flowmeter_delay": "plant file"}


def test_operating_point_takes_the_logs_fuel_temperature_over_the_option():
    data = IOData(u=STEPS, y=FLOW, sample_time=0.02, T_fuel=np.full(STEPS.size, 281.15))
    point = OperatingPoint.of(data, T20)
    assert point.T_fuel == pytest.approx(281.15)
    assert point.to_json()["fuel_temperature"] == pytest.approx(8.0)
    assert point.to_json()["fuel_temperature_source"] == "log"
    assert point.u == pytest.approx(float(np.mean(STEPS)))
    assert OperatingPoint.of(record(STEPS, FLOW), None).to_json()["fuel_temperature"] is None


def test_gain_unit_comes_from_the_signals():
    assert gain_unit(record(STEPS, FLOW)) == "(L/min)/V"
    assert gain_unit(record(STEPS, FLOW, "", "")) == "(output unit)/(input unit)"
