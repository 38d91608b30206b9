"""What each figure rests on (issue 37): control period, spans, undetermined models, bands.

The numbers are the ones that exposed the defects: a loop whose meter reads 0–30 L/min got %/%
gains on the reference plant's 100 L/min (3.3× the gain typed into the block); a reversed clock
gave T = 0.005 s with a 95 % interval 2e-39 … 1.2e34 s and exit 0.
"""

from __future__ import annotations

import math

import pytest

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.plant import load_plant_config
from fuelid.tuning import CommandBand, PISettings, band_check, robustness
from fuelid.workflow import PlantSource, TuneRequest, control_period_from, tune_model, undetermined
from fuelid.workflow._trust import spans_from

MODEL = ProcessModel(K=13.66, T=1.22, T2=0.041, T_f=0.3, delay=0.2)


def test_the_control_period_is_never_assumed():
    with pytest.raises(FuelidError, match="no control period"):
        control_period_from(None, None, None)
    # the option first, then the site file, then the model file's identify run
    assert control_period_from(0.1, 0.2, 0.3).basis == "option"
    assert control_period_from(None, 0.2, 0.3).value == 0.2
    assert control_period_from(None, None, 0.3).basis == "model file"
    # a continuous controller is a given period, not a missing one
    assert control_period_from(0.0).value == 0.0


def test_the_library_refuses_a_request_without_a_period():
    plant = PlantSource(load_plant_config(None))
    with pytest.raises(FuelidError, match="no control period"):
        tune_model(plant, TuneRequest(model=MODEL))


def test_percent_gains_only_on_spans_the_user_gave():
    pi = PISettings(rule="simc", Kc=0.21864, Ti=1.37, control_period=0.1)
    # the loop: the reference spans (4 V, 100 L/min) gave 5.466 %/%, its own 30 L/min
    # meter gives 1.64 %/% (Kc·y_span/u_span, exact)
    assert pi.plc_form(4.0, 100.0)["percent_of_span"]["Kc"] == pytest.approx(5.466, abs=5e-4)
    assert pi.plc_form(4.0, 30.0)["percent_of_span"]["Kc"] == pytest.approx(1.6398, abs=5e-5)
    assert pi.plc_form()["percent_of_span"] is None
    assert pi.plc_form(4.0, 30.0)["percent_of_span"]["Ti_min"] == pytest.approx(1.37 / 60.0)
    spans = spans_from(None, 30.0)
    assert not spans.known
    assert "drive span" in (spans.missing_reason or "")
    spans = spans_from(None, 30.0, site=(4.0, None), plant_file=None)
    assert spans.basis == ["site file", "option"]


def test_without_a_plant_file_no_figure_rests_on_the_reference_plant():
    plant = PlantSource(load_plant_config(None))  # the reference plant standing in
    request = TuneRequest(
        model=MODEL,
        control_period=1.0,
        command_bands=(CommandBand(1.0, 2.0, 14.1, 0.014), CommandBand(2.0, 3.0, 13.4, 0.006)),
    )
    outcome = tune_model(plant, request)
    out = outcome.to_json()
    assert out["temperature_check"] is None
    assert out["plc"]["percent_of_span"] is None
    assert out["spans"]["reason"].startswith("spans not given")
    assert out["command_band_check"]["basis"] == "log"
    assert "reference plant" not in [v for v in out["provenance"].values() if v is not None]
    # with the user's plant file (here the reference plant's own file, given as theirs) the
    # temperature check and the spans are that file's
    mine = PlantSource(plant.config, "reference_plant.toml")
    out = tune_model(mine, request).to_json()
    assert out["provenance"]["temperature_check"] == "plant file"
    assert out["plc"]["percent_of_span"]["y_span"] == 100.0


@pytest.mark.parametrize(
    ("model", "ci95", "fixed", "flagged"),
    [
        # the reversed clock of the issue: T's interval spans 73 decades
        ({"K": 13.7, "T": 0.005}, {"K": (13.6, 13.8), "T": (2e-39, 1.2e34)}, (), ["T"]),
        # an interval that overflowed (null in JSON, read back as inf)
        ({"K": 13.7, "T": 1.2}, {"K": (13.6, 13.8), "T": (0.1, math.inf)}, (), ["T"]),
        # an estimated delay without a standard error
        ({"K": 13.7, "T": 1.2, "delay": 0.3}, {"T": (1.1, 1.3), "delay": None}, (), ["delay"]),
        # a fixed (prior) delay is not judged
        ({"K": 13.7, "T": 1.2, "delay": 0.3}, {"T": (1.1, 1.3), "delay": None}, ("delay",), []),
        # wider than its value: 0.1 ± 0.06 (width 0.12 > 0.1)
        ({"K": 13.7, "T": 0.1}, {"T": (0.04, 0.16)}, (), ["T"]),
        # a dead time of nought, known to 4 ms, in a loop whose lag is 1.2 s: determined
        ({"K": 13.8, "T": 1.2, "delay": 4e-27}, {"T": (1.1, 1.3), "delay": (0.0, 0.004)}, (), []),
        # a dead time of 0.05 ± 0.2 s in that loop: not (width 0.4 > 0.12 = T/10)
        (
            {"K": 13.8, "T": 1.2, "delay": 0.05},
            {"T": (1.1, 1.3), "delay": (0.0, 0.4)},
            (),
            ["delay"],
        ),
        # the tour's model: determined
        ({"K": 13.66, "T": 1.2177}, {"K": (13.66, 13.667), "T": (1.2141, 1.2213)}, (), []),
    ],
)
def test_undetermined_parameters(model, ci95, fixed, flagged):
    found = undetermined(model, ci95, fixed)
    assert [phrase.split(" = ")[0] for phrase in found] == flagged


def test_band_check_moves_only_the_gain():
    pi = PISettings(rule="simc", Kc=1.0, Ti=2.0, control_period=0.0)
    model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    band = CommandBand(1.0, 2.0, 1.2, 0.05)
    check = band_check(pi, model, [band])
    assert check is not None
    # one case per end of the 95 % interval, each exactly the model with that K
    assert [c.K for c in check.cases] == pytest.approx([1.2 - 1.96 * 0.05, 1.2 + 1.96 * 0.05], 1e-3)
    expected = robustness(ProcessModel(K=check.cases[1].K, T=2.0, delay=1.0), pi).Ms
    assert check.worst_Ms == pytest.approx(expected, rel=1e-12)
    # a higher loop gain is less robust (the worked example's Ms ≈ 1.59 at K = 1)
    assert check.worst_Ms > 1.59
    assert band_check(pi, model, []) is None


def test_the_schedule_band_at_the_operating_point_has_the_headline_gains():
    from fuelid.workflow import schedule_gains

    plant = PlantSource(load_plant_config(None), "reference_plant.toml")  # the user's file
    request = TuneRequest(model=MODEL, control_period=1.0, T_fuel=293.15, u=1.9, band_width=35.0)
    headline = tune_model(plant, request).pi
    schedule = schedule_gains(plant, request).schedule
    operating = [band for band in schedule.bands if band.operating]
    assert len(operating) == 1
    band = operating[0]
    assert band.T_low <= 293.15 <= band.T_high
    assert band.u_low <= 1.9 <= band.u_high
    assert (band.design_T, band.design_u) == (293.15, 1.9)
    # the same rule on the same model: the same gains, unless detuned for the band's other cases
    assert band.pi.Kc == pytest.approx(headline.Kc * band.detune, rel=1e-12)
    assert band.pi.Ti == pytest.approx(headline.Ti, rel=1e-12)
    for other in schedule.bands:
        assert other.T_low <= other.design_T <= other.T_high
        assert other.u_low <= other.design_u <= other.u_high
