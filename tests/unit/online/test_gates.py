"""Gates on identification windows (fuelid.online.gates) on synthetic 50 Hz, 600 s windows."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.signal

from fuelid.errors import NotExcitingError
from fuelid.identify import OutputError
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model
from fuelid.online import Online
from fuelid.online.gates import (
    WindowVerdict,
    bad_share,
    excitation_refusal,
    gate_estimator,
    judged_mode,
    lost_samples,
    postfit_gates,
    prefit_gates,
    prefit_samples,
)
from fuelid.store import Quality, SampleArrays

H = 0.02  # 50 Hz [s]
WINDOW_S = 600.0
N = round(WINDOW_S / H)
T = np.arange(N) * H
SETTINGS = Online()
PLANT = ProcessModel(K=10.0, T=1.0, delay=0.2)  # (L/min)/V, s


def _man_steps() -> np.ndarray:
    """Command steps every 30 s between 2.5 and 3.5 V."""
    return np.where((T // 30.0) % 2 == 0, 2.5, 3.5)


def _window(
    u: np.ndarray,
    y: np.ndarray,
    setpoint: np.ndarray | None = None,
    mode: int = 0,
    ok: np.ndarray | None = None,
) -> WindowVerdict:
    sp = np.full(N, np.nan) if setpoint is None else setpoint
    good = np.ones(N, bool) if ok is None else ok
    return prefit_gates(T, u, y, sp, np.full(N, mode), good, SETTINGS)


def _open_loop(u: np.ndarray, rng: np.random.Generator, noise: float = 0.3) -> np.ndarray:
    return 10.0 + simulate_model(PLANT, u, H) + rng.normal(scale=noise, size=u.size)


# --- pre-fit --------------------------------------------------------------------------------------


def test_man_steps_accepted_with_their_times():
    rng = np.random.default_rng(1)
    u = _man_steps()
    v = _window(u, _open_loop(u, rng))
    assert v.accepted, v.reasons
    assert v.reasons == ()
    assert v.mode == "MAN"
    assert v.excitation_events == pytest.approx(np.arange(30.0, 600.0, 30.0), abs=H)
    assert v.measured["command_step_threshold_V"] == 0.05


def test_man_flat_rejected():
    rng = np.random.default_rng(2)
    u = np.full(N, 3.0)
    v = _window(u, _open_loop(u, rng))
    assert not v.accepted
    assert v.reasons == ("MAN without command moves (no step above 0.05 V)",)
    assert v.excitation_events == ()


def test_man_command_noise_is_no_excitation():
    rng = np.random.default_rng(3)
    # command noise 0.03 V: threshold 3 × 0.03 = 0.09 V; about 3 % of the sample differences
    # exceed it, but none holds
    u = 3.0 + rng.normal(scale=0.03, size=N)
    assert np.sum(np.abs(np.diff(u)) > 0.09) > 500
    v = _window(u, _open_loop(u, rng))
    assert v.measured["command_step_threshold_V"] == pytest.approx(0.09, rel=0.05)
    assert len(v.reasons) == 1
    assert v.reasons[0].startswith("MAN without command moves (no step above 0.0")
    stepped = u + np.where(T < 300.0, 0.0, 0.3)
    v2 = _window(stepped, _open_loop(stepped, rng))
    assert v2.accepted, v2.reasons
    assert v2.excitation_events == pytest.approx([300.0], abs=H)


def _auto_flow(rng: np.random.Generator, sp: np.ndarray) -> np.ndarray:
    """Closed-loop flow: setpoint tracked with a 1 s lag, a slow coloured disturbance, noise."""
    tracked = scipy.signal.lfilter([1.0 - np.exp(-H)], [1.0, -np.exp(-H)], sp - sp[0]) + sp[0]
    slow = scipy.signal.lfilter([1.0], [1.0, -0.999], rng.normal(scale=0.05, size=N))
    return tracked + slow + rng.normal(scale=0.1, size=N)


def test_auto_steady_setpoint_with_coloured_disturbance_rejected():
    rng = np.random.default_rng(4)
    sp = np.full(N, 40.0)
    y = _auto_flow(rng, sp)
    assert np.ptp(y) > 1.0  # the disturbance moves the flow well beyond the 0.5 L/min band
    u = 3.0 + 0.1 * (sp - y)  # the controller reacts: u moves, which is no excitation
    v = _window(u, y, sp, mode=1)
    assert not v.accepted
    assert v.mode == "AUTO"
    assert len(v.reasons) == 1
    assert v.reasons[0].startswith("no excitation: the setpoint did not move")
    assert v.excitation_events == ()


def test_auto_two_setpoint_steps_pass_with_their_times():
    rng = np.random.default_rng(5)
    sp = np.where(T < 200.0, 40.0, np.where(T < 400.0, 45.0, 38.0))
    y = _auto_flow(rng, sp)
    v = _window(3.0 + 0.05 * (y - 40.0), y, sp, mode=1)
    assert v.accepted, v.reasons
    assert len(v.excitation_events) == 2
    assert v.excitation_events == pytest.approx([200.0, 400.0], abs=H)
    assert v.measured["setpoint_threshold_Lpm"] == 0.5


def test_mixed_window_judged_by_the_majority_mode():
    rng = np.random.default_rng(6)
    u = _man_steps()
    y = _open_loop(u, rng)
    mode = np.where(T < 400.0, 1, 0)  # two thirds AUTO with a steady setpoint
    v = prefit_gates(T, u, y, np.full(N, 40.0), mode, np.ones(N, bool), SETTINGS)
    assert v.mode == "AUTO"
    assert not v.accepted
    assert "the setpoint did not move" in v.reason
    assert judged_mode(np.where(T < 200.0, 1, 0), np.ones(N, bool)) == "MAN"


def test_ten_percent_flagged_rejected_with_the_share():
    rng = np.random.default_rng(7)
    u = _man_steps()
    ok = np.ones(N, bool)
    ok[rng.choice(N, size=N // 10, replace=False)] = False
    v = _window(u, _open_loop(u, rng), ok=ok)
    assert not v.accepted
    assert v.measured["bad_share"] == pytest.approx(0.10)
    assert v.reasons == ("gaps or bad quality: 10.0 % of the window (limit 5 %)",)


def test_gaps_count_as_lost_samples():
    rng = np.random.default_rng(8)
    u = _man_steps()
    y = _open_loop(u, rng)
    keep = (T < 100.0) | (T >= 160.0)  # one minute missing: 3000 of 30 000 samples
    assert lost_samples(T[keep]) == 3000
    share = bad_share(T[keep], np.ones(int(keep.sum()), bool))
    assert share == pytest.approx(0.1)
    v = prefit_gates(
        T[keep],
        u[keep],
        y[keep],
        np.full(keep.sum(), np.nan),
        np.zeros(keep.sum()),
        np.ones(keep.sum(), bool),
        SETTINGS,
    )
    assert v.reasons[0] == "gaps or bad quality: 10.0 % of the window (limit 5 %)"
    seq = np.arange(N)[keep]
    assert lost_samples(T[keep], seq=seq) == 3000


def test_output_at_the_limit_rejected():
    rng = np.random.default_rng(9)
    u = _man_steps()
    u[T >= 480.0] = 5.0  # the last 120 s, 20 % of the window, at the upper limit
    v = _window(u, _open_loop(u, rng))
    assert not v.accepted
    assert v.measured["limit_share"] == pytest.approx(0.2)
    assert v.reasons == ("output at a limit: 20.0 % of the window (limit 5 %)",)


def test_every_failed_gate_is_listed():
    rng = np.random.default_rng(10)
    u = np.full(N, 5.0)
    ok = np.ones(N, bool)
    ok[: N // 5] = False
    v = _window(u, _open_loop(u, rng), ok=ok)
    assert [r.split(":")[0] for r in v.reasons] == [
        "gaps or bad quality",
        "output at a limit",
        "MAN without command moves (no step above 0.05 V)",
    ]


def test_store_samples_and_json():
    rng = np.random.default_rng(11)
    u = _man_steps()
    y = _open_loop(u, rng)
    quality = np.full(N, int(Quality.OK))
    quality[:600] = int(Quality.STALE)  # 2 %: under the 5 % limit
    samples = SampleArrays(
        time=1.7e9 + T,
        seq=np.arange(N, dtype=np.int64),
        u=u,
        y=y,
        setpoint=np.full(N, np.nan),
        fuel_temperature=np.full(N, 20.0),
        mode=np.zeros(N, dtype=np.int64),
        quality=quality,
    )
    v = prefit_samples(samples, SETTINGS)
    assert v.accepted, v.reasons
    assert v.measured["bad_share"] == pytest.approx(0.02)
    d = json.loads(json.dumps(v.to_json(), allow_nan=False))
    assert d["accepted"] is True
    assert d["reason"] == "passed every gate"
    assert len(d["excitation_events_s"]) == 19


# --- post-fit -------------------------------------------------------------------------------------


def _fit(u: np.ndarray, y: np.ndarray) -> tuple[OutputError, IOData]:
    data = IOData(u=u, y=y, sample_time=H)
    return OutputError(order=1).fit(data), data


def test_white_noise_fit_accepted():
    rng = np.random.default_rng(12)
    u = _man_steps()
    est, data = _fit(u, _open_loop(u, rng))
    v = gate_estimator(est, data, SETTINGS)
    assert v.accepted, v.reasons
    assert v.measured["rel_stderr_K"] < 0.01
    assert v.measured["residual_acf_max"] < 0.05
    assert v.measured["fit_percent"] > 90.0
    assert v.events == ()


def _ar1(rng: np.random.Generator, pole: float, sd: float, n: int = N) -> np.ndarray:
    """AR(1) noise of stationary standard deviation ``sd``."""
    w = rng.normal(scale=sd * np.sqrt(1.0 - pole**2), size=n)
    return scipy.signal.lfilter([1.0], [1.0, -pole], w)


def test_ar1_noise_with_a_correct_model_passes_after_prewhitening():
    # Bands stated before running. Noise AR(1), pole 0.8 per sample (the gate study's), sd
    # 0.3 L/min; the model structure is right, so the residual is the noise: raw ρ(1) = 0.8
    # (sd of its estimate √((1 − 0.8²)/N) = 0.0035; band ≥ 0.75). The noise's AR fitted on the
    # settled samples (≈ 20 × (1500 − 2 × 4 s / h) ≈ 22 000) is order 1, a₁ = −0.8 ± 4·0.004.
    # Prewhitened, ρ(k) of white noise over N = 30 000 samples has sd 1/√N = 0.0058; the
    # largest |ρ| over ~1000 lags is ≈ √(2 ln 2000)/√N = 0.022, and above 5/√N = 0.029 with
    # probability about 2000 × 2.9e-7 < 0.1 %: band ≤ 5/√N.
    rng = np.random.default_rng(13)
    u = _man_steps()
    y = 10.0 + simulate_model(PLANT, u, H) + _ar1(rng, 0.8, 0.3)
    est, data = _fit(u, y)
    v = gate_estimator(est, data, SETTINGS)
    m = v.measured
    assert m["residual_acf_basis"] == "prewhitened"
    assert m["residual_acf_raw_max"] >= 0.75
    assert m["residual_acf_raw_lag"] == 1
    assert m["residual_acf_noise_ar_order"] == 1
    assert 15_000 < m["residual_acf_settled_samples"] < 25_000
    assert m["residual_acf_max"] <= 5.0 / np.sqrt(N)
    assert 1000 <= m["residual_acf_lags"] <= 1060  # 5 settling times of the model (4.1 s)
    assert v.accepted, v.reasons


def test_missing_lag_still_gives_a_large_statistic_under_coloured_noise():
    # The plant has a second lag 0.3·T the fit (order fixed to 1, delay fixed) cannot follow:
    # the misfit m(k) after each step is the model's error, not noise. Prewhitening by the
    # noise's A(q) = 1 − 0.8q⁻¹ (fitted where the output has settled, where m has decayed)
    # keeps it: with m' = A(q)·m (from the same fit on the noise-free output) and the
    # innovation's variance σ_e² = (1 − 0.8²)·sd², ρ(1) ≈ ρ_m'(1)·var m'/(var m' + σ_e²).
    # Band: the prediction ± 0.05 (estimation spread ~1/√N plus the fit's noise), and far
    # above the 5/√N of a correct model.
    sd = 0.03  # L/min: 0.3 % of the 10 L/min steps
    plant = ProcessModel(K=10.0, T=1.0, T2=0.3, delay=0.2)
    u = _man_steps()
    clean = 10.0 + simulate_model(plant, u, H)
    misfit = clean - OutputError(order=1, delay=0.2).fit(IOData(u=u, y=clean, sample_time=H)).y_hat_
    filtered = scipy.signal.lfilter([1.0, -0.8], [1.0], misfit)[1:]
    filtered -= filtered.mean()
    r0, r1 = filtered @ filtered / filtered.size, filtered[1:] @ filtered[:-1] / filtered.size
    predicted = r1 / (r0 + (1.0 - 0.8**2) * sd**2)
    assert 0.7 < predicted < 0.85  # the window is designed so (a plain check of the setup)
    y = clean + _ar1(np.random.default_rng(17), 0.8, sd)
    data = IOData(u=u, y=y, sample_time=H)
    est = OutputError(order=1, delay=0.2).fit(data)
    v = gate_estimator(est, data, SETTINGS)
    m = v.measured
    assert est.model_.T2 == 0.0
    assert m["residual_acf_basis"] == "prewhitened"
    assert m["residual_acf_noise_ar_order"] >= 1
    assert m["residual_acf_max"] == pytest.approx(predicted, abs=0.05)
    assert m["residual_acf_max"] > 20 * 5.0 / np.sqrt(N)
    assert m["residual_acf_raw_max"] > m["residual_acf_max"]


def test_too_few_settled_samples_judges_the_raw_residuals():
    # command moves every 2 s, the model settles in ~4 s: no settled stretch, so the noise
    # cannot be modelled; the raw residuals of AR(1) noise (pole 0.99) are judged, and say so
    rng = np.random.default_rng(13)
    u = np.where((T // 2.0) % 2 == 0, 2.5, 3.5)
    y = 10.0 + simulate_model(PLANT, u, H) + _ar1(rng, 0.99, 0.3)
    est, data = _fit(u, y)
    v = gate_estimator(est, data, SETTINGS)
    m = v.measured
    assert m["residual_acf_basis"] == "raw: too few settled samples (n < 500)"
    assert m["residual_acf_noise_ar_order"] is None
    assert m["residual_acf_settled_samples"] is None
    rho, lags = m["residual_acf_max"], m["residual_acf_lags"]
    assert rho == m["residual_acf_raw_max"] > 0.9
    assert m["residual_acf_lag"] == 1
    assert not v.accepted
    acf = [r for r in v.reasons if r.startswith("residual correlation too large")]
    limit = SETTINGS.max_residual_acf
    assert acf == [
        f"residual correlation too large: |ρ(1)| = {rho:.3f} > {limit:g} (lags 1–{lags}, "
        "raw: too few settled samples to model the noise)"
    ]


def test_prediction_errors_are_judged_as_they_are():
    rng = np.random.default_rng(18)
    e = _ar1(rng, 0.8, 0.3)
    v = postfit_gates(PLANT, {"K": 0.01, "T": 0.01}, 95.0, e, H, SETTINGS)
    m = v.measured
    assert m["residual_acf_basis"] == "raw: no command given (prediction errors)"
    assert m["residual_acf_max"] == m["residual_acf_raw_max"] == pytest.approx(0.8, abs=0.02)
    assert not v.accepted


def test_short_noisy_window_rejected_on_the_standard_errors():
    rng = np.random.default_rng(14)
    t = np.arange(0.0, 8.0, H)
    u = np.where(t < 2.0, 3.0, 3.1)
    y = 10.0 + simulate_model(PLANT, u, H) + rng.normal(scale=1.0, size=t.size)
    data = IOData(u=u, y=y, sample_time=H)
    est = OutputError(order=1, delay=0.2).fit(data)
    v = gate_estimator(est, data, SETTINGS)
    assert not v.accepted
    se_reasons = [r for r in v.reasons if r.startswith("relative standard error of")]
    assert se_reasons
    assert v.measured["rel_stderr_K"] > SETTINGS.max_rel_stderr_K
    assert se_reasons[0].startswith("relative standard error of K")
    assert v.measured["rel_stderr_T"] > SETTINGS.max_rel_stderr_T
    assert any(r.startswith("relative standard error of T") for r in v.reasons)


def test_plant_ratio_is_an_event_not_a_rejection():
    rng = np.random.default_rng(15)
    u = _man_steps()
    est, data = _fit(u, _open_loop(u, rng))
    v = gate_estimator(est, data, SETTINGS, plant_K=PLANT.K / 2.5)
    assert v.accepted, v.reasons
    assert v.measured["plant_ratio"] == pytest.approx(2.5, rel=0.01)
    assert len(v.events) == 1
    assert v.events[0].startswith("plant_ratio: the identified K is 2.50 × the plant model's")
    inside = gate_estimator(est, data, SETTINGS, plant_K=PLANT.K / 1.5)
    assert inside.events == ()


def test_poor_validation_fit_rejected():
    rng = np.random.default_rng(16)
    u = _man_steps()
    est, data = _fit(u, _open_loop(u, rng))
    v = gate_estimator(est, data, SETTINGS, validation_fit_percent=61.0)
    assert v.reasons == ("poor validation fit: 61.0 % < 80 %",)


def test_estimator_refusal_and_combination():
    u = np.full(N, 3.0)
    data = IOData(u=u, y=np.full(N, 40.0), sample_time=H)
    with pytest.raises(NotExcitingError) as info:
        OutputError().fit(data)
    refused = excitation_refusal(info.value)
    assert refused.reasons == ("no excitation: the input never changes: nothing to identify",)
    pre = WindowVerdict.of([], {"bad_share": 0.0}, excitation_events=[30.0], mode="MAN")
    both = pre.combine(refused)
    assert not both.accepted
    assert both.mode == "MAN"
    assert both.excitation_events == (30.0,)
    assert both.reasons == refused.reasons
