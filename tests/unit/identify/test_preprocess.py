"""Preprocessing on synthetic records whose answers the construction fixes.

The loop record: PLC samples every h = 0.02 s of a first-order flow response (gain K = 8 L/min/V,
time constant T = 2 s, operating point 1 V → 14.6 L/min) to a command that the controller
updates on a 1 s grid: 1.0 V, then 1.5 V at t = 5 s, 1.2 V at 12 s and 1.6 V at 20 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from fuelid.errors import DataError
from fuelid.identify.preprocess import decimate, lowpass, select
from fuelid.io.timeseries import IOData

FloatArray = NDArray[np.float64]
H = 0.02
K, T, U0, Y0 = 8.0, 2.0, 1.0, 14.6
STEPS = ((5.0, 1.5), (12.0, 1.2), (20.0, 1.6))  # (time [s], new command [V])


def loop_record(duration: float = 30.0, noise: float = 0.0, seed: int = 0) -> IOData:
    """The loop record from t = 0 (at rest), exact first-order response plus white noise."""
    n = round(duration / H)
    t = H * np.arange(n)
    u = np.full(n, U0)
    y = np.full(n, Y0)
    level = U0
    for t_step, value in STEPS:
        k = round(t_step / H)  # integer sample index: the step lies exactly on an update instant
        u[k:] = value
        y[k:] += K * (value - level) * (1.0 - np.exp(-(t[k:] - t[k]) / T))
        level = value
    y += noise * np.random.default_rng(seed).standard_normal(n)
    return IOData(u, y, H, source="synthetic")


def sine_record(freq: float, duration: float = 40.0, phase: float = 0.3) -> IOData:
    """Unit sinusoid of ``freq`` [Hz] as the output; constant input."""
    t = H * np.arange(round(duration / H))
    return IOData(np.ones_like(t), np.sin(2 * np.pi * freq * t + phase), H)


def amplitude_phase(data: IOData, freq: float, skip: float = 5.0) -> tuple[float, float]:
    """Amplitude and phase of the ``freq`` component of y, fitted away from the ends."""
    t = data.t
    inner = (t > t[0] + skip) & (t < t[-1] - skip)
    w = 2 * np.pi * freq * t[inner]
    basis = np.column_stack([np.sin(w), np.cos(w)])
    (a, b), *_ = np.linalg.lstsq(basis, data.y[inner], rcond=None)
    return math.hypot(a, b), math.atan2(b, a)


def change_times(data: IOData) -> FloatArray:
    """Times [s] of the samples at which u differs from the sample before."""
    return data.t[np.flatnonzero(np.diff(data.u)) + 1]


# ---------------------------------------------------------------- lowpass


def test_lowpass_keeps_a_slow_sinusoid_in_amplitude_and_phase() -> None:
    data = sine_record(0.1)
    out = lowpass(data, cutoff_hz=2.0)
    amplitude, phase = amplitude_phase(out, 0.1)
    # |H|² = 1/(1 + (0.1/2)^8) = 1 − 4e-11: unity; zero phase by forward–backward filtering
    assert amplitude == pytest.approx(1.0, abs=1e-6)
    assert phase == pytest.approx(0.3, abs=1e-6)
    # zero lag: the peaks (every 10 s = 500 samples) sit on the same samples
    period = 500
    for start in range(250, data.n_samples - period - 250, period):
        window = slice(start, start + period)
        assert abs(int(np.argmax(out.y[window])) - int(np.argmax(data.y[window]))) <= 1
    np.testing.assert_array_equal(out.u, data.u)  # the held command is never filtered
    assert out.sample_time == H
    assert out.notes[-1] == "y low-passed: zero-phase Butterworth, order 4, cutoff 2 Hz"


@pytest.mark.parametrize(
    ("freq", "cutoff", "order"),
    [(1.5, 1.0, 4), (1.0, 1.0, 2), (3.0, 1.0, 2)],
)
def test_lowpass_attenuates_like_a_squared_butterworth(
    freq: float, cutoff: float, order: int
) -> None:
    out = lowpass(sine_record(freq), cutoff_hz=cutoff, order=order)
    amplitude, phase = amplitude_phase(out, freq)
    # filtfilt applies |H| twice: |H|² = 1/(1 + (f/f_c)^(2n)) for the analog Butterworth; the
    # digital design (bilinear transform, prewarped at f_c) replaces f by tan(π·f·h)/(π·h)
    analog = 1.0 / (1.0 + (freq / cutoff) ** (2 * order))
    warp = math.tan(math.pi * freq * H) / math.tan(math.pi * cutoff * H)
    digital = 1.0 / (1.0 + warp ** (2 * order))
    assert amplitude == pytest.approx(digital, rel=1e-4)
    assert amplitude == pytest.approx(analog, rel=0.05)  # warping at f ≤ 3 Hz, Nyquist 25 Hz
    assert phase == pytest.approx(0.3, abs=1e-6)


def test_lowpass_at_the_cutoff_halves_the_amplitude_exactly() -> None:
    # the digital design places |H(f_c)|² = 1/2 exactly (prewarped), so filtfilt gives 1/2
    amplitude, _ = amplitude_phase(lowpass(sine_record(1.0), cutoff_hz=1.0), 1.0)
    assert amplitude == pytest.approx(0.5, abs=1e-6)


@pytest.mark.parametrize("cutoff", [0.0, -1.0, 25.0, 30.0, math.nan])
def test_lowpass_refuses_a_cutoff_outside_zero_to_nyquist(cutoff: float) -> None:
    with pytest.raises(DataError, match=r"Nyquist frequency 25 Hz"):
        lowpass(sine_record(0.1), cutoff_hz=cutoff)


def test_lowpass_refuses_a_record_shorter_than_the_padding() -> None:
    # order 4 → two second-order sections → sosfiltfilt pads with 3·(2·2 + 1) = 15 samples
    data = IOData(np.ones(15), np.zeros(15), H)
    with pytest.raises(DataError, match=r"pads each end with 15 samples.*\(15 given\)"):
        lowpass(data, cutoff_hz=1.0)
    # order 1: one first-order section (b2 = a2 = 0) → 3·(2·1 + 1 − 1) = 6 samples suffice
    assert lowpass(data, cutoff_hz=1.0, order=1).n_samples == 15


# ---------------------------------------------------------------- decimate


def test_decimate_by_50_lands_on_the_update_instants() -> None:
    data = loop_record()
    out = decimate(data, 1.0)
    assert out.sample_time == 1.0
    assert out.t0 == 0.0
    assert out.n_samples == 30
    np.testing.assert_array_equal(change_times(out), [5.0, 12.0, 20.0])
    # u[j] is the command held over [t_j, t_j + 1 s): the PLC value at t_j
    np.testing.assert_array_equal(out.u, data.u[::50])
    assert out.u[[4, 5, 11, 12, 19, 20]].tolist() == [1.0, 1.5, 1.5, 1.2, 1.2, 1.6]
    assert "phase 0" in out.notes[-1]
    assert out.notes[-2].startswith("y low-passed")  # the anti-aliasing filter: 0.4 Hz
    assert "cutoff 0.4 Hz" in out.notes[-2]


def test_decimate_finds_the_update_phase_when_the_record_starts_between_updates() -> None:
    data = loop_record(31.0).segment(15)  # starts at t = 0.3 s, 35 samples before an update
    assert data.t0 == pytest.approx(0.3)
    out = decimate(data, 1.0)
    assert out.t0 == 1.0
    assert "phase 35" in out.notes[-1]
    np.testing.assert_allclose(change_times(out), [5.0, 12.0, 20.0], atol=1e-9)
    # a fixed phase 0 would sample 0.3 s after each update instead
    late = decimate(data, 1.0, phase=0)
    np.testing.assert_allclose(change_times(late), [5.3, 12.3, 20.3], atol=1e-9)


def test_decimated_output_of_a_slow_signal_equals_the_original_samples() -> None:
    base = loop_record()
    slow = 14.6 + 2.0 * np.sin(2 * np.pi * 0.02 * base.t + 0.3)
    data = IOData(base.u, slow, H)
    out = decimate(data, 1.0)
    original = slow[::50]
    # at 0.02 Hz the 0.4 Hz filter's gain is 1 − (0.05)^8 ≈ 1 − 4e-11: in the interior only
    # rounding remains; near the ends the odd-reflection padding leaves a small transient
    np.testing.assert_allclose(out.y[5:-5], original[5:-5], atol=1e-5)
    np.testing.assert_allclose(out.y, original, atol=2e-3)
    without = decimate(data, 1.0, antialias=False)
    np.testing.assert_array_equal(without.y, original)
    assert len(without.notes) == 1


@pytest.mark.parametrize("period", [1.01, 0.03, 0.5 + 1e-5])
def test_decimate_refuses_a_non_integer_factor(period: float) -> None:
    with pytest.raises(DataError, match=r"not an integer multiple of the sample time 0\.02 s"):
        decimate(loop_record(), period)


def test_decimate_refuses_a_bad_phase_and_too_short_a_result() -> None:
    with pytest.raises(DataError, match=r"phase must lie in 0 … 49, got 50"):
        decimate(loop_record(), 1.0, phase=50)
    with pytest.raises(DataError, match="fewer than 2 samples"):
        decimate(loop_record().segment(0, 50), 1.0)


def test_decimate_without_changes_of_u_uses_phase_0() -> None:
    data = IOData(np.ones(500), np.linspace(0.0, 1.0, 500), H, t0=3.0)
    out = decimate(data, 0.5, antialias=False)
    assert out.t0 == 3.0
    assert out.sample_time == 0.5
    np.testing.assert_array_equal(out.y, data.y[::25])


# ---------------------------------------------------------------- select


def test_select_keeps_start_and_drops_stop() -> None:
    data = loop_record()
    out = select(data, 5.0, 12.0)
    assert out.t0 == pytest.approx(5.0)
    assert out.n_samples == 350  # 5.00, 5.02, …, 11.98
    assert out.t[-1] == pytest.approx(11.98)
    assert out.u[0] == 1.5  # the step at 5 s is inside, the one at 12 s is not
    assert np.all(out.u == 1.5)
    assert out.notes[-1] == "selected t = 5 … 11.98 s (350 samples)"
    assert select(data, t_stop=1.0).n_samples == 50
    assert select(data, t_start=29.0).n_samples == 50


@pytest.mark.parametrize(
    ("start", "stop", "message"),
    [
        (40.0, 50.0, "selects no samples"),
        (12.0, 5.0, "selects no samples"),
        (10.0, 10.1, "selects only 5 samples"),
    ],
)
def test_select_refuses_empty_and_tiny_windows_naming_the_span(
    start: float, stop: float, message: str
) -> None:
    with pytest.raises(DataError, match=message) as info:
        select(loop_record(), start, stop)
    assert "the record spans t = 0 … 29.98 s (1500 samples of 0.02 s)" in str(info.value)


# ---------------------------------------------------------------- offsets


# ---------------------------------------------------------------- detrend


# ---------------------------------------------------------------- all


def test_nothing_is_mutated_and_each_step_adds_a_note() -> None:
    data = loop_record(noise=0.05).with_notes("loaded")
    u, y = data.u.copy(), data.y.copy()
    out = select(data, 1.0, 29.0)
    out = lowpass(out, 5.0)
    out = decimate(out, 1.0)
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y, y)
    assert data.notes == ("loaded",)
    assert out.notes[0] == "loaded"
    assert len(out.notes) == 5  # loaded, select, lowpass, lowpass (anti-alias), decimate
    assert out.sample_time == 1.0
    assert out.t0 == 1.0
    assert out.source == "synthetic"
