"""Logs with gaps: one model for all segments, each segment with its own initial state.

The truth is the first-order-plus-delay model the output-error fit estimates, so the fit of the
record with gaps must be unbiased to within its standard errors (which the joint covariance
gives over all segments), and close to the fit of the same record without the gaps removed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuelid.errors import FuelidError
from fuelid.identify import (
    MIN_SEGMENT_SAMPLES,
    IdentifyOptions,
    OutputError,
    StepResponseLS,
    drop_short_segments,
    identify,
    input_residual_correlation,
    steady_state_errors,
)
from fuelid.identify._diagnostics import _normalised_xcorr
from fuelid.identify.preprocess import decimate, join_segments, lowpass, select
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, nrmse_fit, simulate_model

H = 0.1
TRUTH = ProcessModel(K=3.0, T=2.0, delay=0.4)
SIGMA = 0.05
OFFSET = 20.0
#: samples removed at each cut (the gaps): both in the middle of a transient
CUTS = ((1010, 1060), (2020, 2080))


def _record() -> tuple[IOData, IOData, np.ndarray]:
    """The contiguous record, the same with the samples at the cuts removed, and the truth."""
    rng = np.random.default_rng(7)
    u = np.repeat(rng.choice([1.0, 1.5, 2.0, 2.5, 3.0], 60), 50)
    clean = OFFSET + simulate_model(TRUTH, u, H)
    y = clean + rng.normal(0.0, SIGMA, u.size)
    keep = np.ones(u.size, dtype=bool)
    for a, b in CUTS:
        keep[a:b] = False
    t = H * np.arange(u.size)
    starts = (CUTS[0][0], CUTS[0][0] + CUTS[1][0] - CUTS[0][1])
    gapped = IOData(
        u[keep],
        y[keep],
        H,
        segment_starts=starts,
        segment_t0=(float(t[CUTS[0][1]]), float(t[CUTS[1][1]])),
    )
    return IOData(u, y, H), gapped, clean[keep]


FULL, GAPPED, CLEAN = _record()


def test_the_record_has_three_segments_that_start_away_from_rest():
    assert GAPPED.n_segments == 3
    for a, _ in GAPPED.segment_bounds()[1:]:
        # the noise-free output at a segment's start is far (≫ σ) from the rest value of its
        # first command: the initial state must be estimated per segment
        rest = OFFSET + TRUTH.K * (GAPPED.u[a] - FULL.u[0])
        assert abs(CLEAN[a] - rest) > 5 * SIGMA


def test_joint_fit_is_unbiased_and_matches_the_contiguous_fit():
    joint = OutputError(order=1, delay=TRUTH.delay).fit(GAPPED)
    full = OutputError(order=1, delay=TRUTH.delay).fit(FULL)
    # one initial state per segment, in the covariance with the rest
    assert joint.param_names_ == ("K", "T", "offset", "c0", "c0_seg2", "c0_seg3")
    assert joint.cov_.shape == (6, 6)
    for name, true in (("K", TRUTH.K), ("T", TRUTH.T)):
        se = joint.stderr_[name]
        assert se is not None
        assert abs(getattr(joint, f"{name}_") - true) < 4 * se
        # 97 % of the samples and two more nuisance parameters: about the same precision
        se_full = full.stderr_[name]
        assert se_full is not None
        assert se_full < se < 1.15 * se_full
        assert abs(getattr(joint, f"{name}_") - getattr(full, f"{name}_")) < 2 * se
    assert joint.sigma_ == pytest.approx(SIGMA, rel=0.05)
    assert joint.fit_percent_ == pytest.approx(full.fit_percent_, abs=0.5)


def test_ignoring_the_gaps_or_interpolating_across_them_biases_the_fit():
    joint = OutputError(order=1, delay=TRUTH.delay).fit(GAPPED)
    se_T = joint.stderr_["T"]
    assert se_T is not None
    # naive concatenation: the output jumps at the joins, the model is made to follow them
    naive = OutputError(order=1, delay=TRUTH.delay).fit(IOData(GAPPED.u, GAPPED.y, H))
    # interpolation across the gaps: invented samples the plant never produced
    t = FULL.t
    filled = IOData(np.interp(t, GAPPED.t, GAPPED.u), np.interp(t, GAPPED.t, GAPPED.y), H)
    interpolated = OutputError(order=1, delay=TRUTH.delay).fit(filled)
    for wrong in (naive, interpolated):
        assert abs(wrong.T_ - TRUTH.T) > 10 * se_T
        assert abs(wrong.T_ - TRUTH.T) > 10 * abs(joint.T_ - TRUTH.T)
    assert naive.fit_percent_ < joint.fit_percent_ - 5.0
    assert naive.sigma_ > 2 * SIGMA


def test_simulate_predict_and_score_run_per_segment():
    est = OutputError(order=1, delay=TRUTH.delay).fit(GAPPED)
    fitted = est.simulate(GAPPED)
    np.testing.assert_allclose(fitted, est.y_hat_, rtol=0, atol=1e-12)
    # the fitted simulation follows the noise-free truth to a fraction of the noise
    assert np.sqrt(np.mean((fitted - CLEAN) ** 2)) < 0.2 * SIGMA
    # re-estimated initial states on the same record: the same fit
    assert est.score(GAPPED, initial="estimate") == pytest.approx(est.fit_percent_, abs=0.01)
    # from rest at each segment's first command: the segments' transients are missed
    rest = est.simulate(GAPPED, initial="rest")
    np.testing.assert_allclose(est.predict(GAPPED, horizon=3), rest)
    assert nrmse_fit(GAPPED.y, rest) < est.fit_percent_ - 2.0
    # each segment restarts: nothing of the previous segment carries over the gap
    (a, b) = GAPPED.segment_bounds()[1]
    alone = est.simulate(GAPPED.segment(a, b), initial="rest")
    np.testing.assert_allclose(rest[a:b], alone, rtol=0, atol=1e-9)


def test_fitted_simulation_continues_into_a_segment_after_the_fitting_record():
    n_fit = 900  # inside the first segment: the held-out part holds both gaps
    est = OutputError(order=1, delay=TRUTH.delay).fit(GAPPED.segment(0, n_fit))
    y_hat = est.simulate(GAPPED, initial="fitted")
    # the later segments' initial states are estimated on their own samples
    assert np.sqrt(np.mean((y_hat[n_fit:] - CLEAN[n_fit:]) ** 2)) < 0.3 * SIGMA
    moved = IOData(GAPPED.u, GAPPED.y, H, segment_starts=(500,), segment_t0=(80.0,))
    with pytest.raises(FuelidError, match="gaps elsewhere"):
        est.simulate(moved, initial="fitted")


def test_a_segment_too_short_for_its_initial_state_is_refused_or_left_out():
    u, y = GAPPED.u, GAPPED.y
    short = IOData(u[:1500], y[:1500], H, segment_starts=(1000, 1010), segment_t0=(105.0, 200.0))
    with pytest.raises(FuelidError, match=f"fewer than {MIN_SEGMENT_SAMPLES} samples"):
        OutputError(order=1, delay=0.4).fit(short)
    kept, why = drop_short_segments(short)
    assert kept.n_samples == 1490
    assert kept.n_segments == 2
    assert "has only 10 samples" in why[0]
    result = identify(short, IdentifyOptions(order=1, delay=0.4))
    assert any("has only 10 samples" in w and "left out" in w for w in result.warnings)
    assert result.to_json()["segments"] == 2
    assert result.y_hat.size == 1490


def test_identify_fits_all_segments_and_reports_them():
    result = identify(GAPPED, IdentifyOptions(order=1, delay=TRUTH.delay))
    contiguous = identify(FULL, IdentifyOptions(order=1, delay=TRUTH.delay))
    doc = result.to_json()
    assert doc["segments"] == 3
    assert contiguous.to_json()["segments"] == 1
    assert set(contiguous.to_json()) <= set(doc)
    assert result.y_hat.size == GAPPED.n_samples
    np.testing.assert_array_equal(result.time, GAPPED.t)  # true times, jumping at the gaps
    assert result.fit_percent == pytest.approx(nrmse_fit(GAPPED.y, result.y_hat), abs=1e-12)
    # white noise and the true structure: no test fails, nothing to warn about
    assert result.warnings == []
    assert result.diagnostics["residual_whiteness"]["passed"]
    assert result.diagnostics["input_residual_correlation"]["passed"]


@pytest.mark.parametrize("fraction", [0.4, 0.32, 0.05])
def test_validation_split_of_a_log_with_gaps(fraction: float):
    # 0.4: the held-out tail starts in the second segment and crosses the second gap;
    # 0.32: it starts in the third segment; 0.05: inside the last one
    options = IdentifyOptions(order=1, delay=TRUTH.delay, validate_split=fraction)
    result = identify(GAPPED, options)
    contiguous = identify(FULL, options)
    assert result.validation_fit_percent is not None
    assert contiguous.validation_fit_percent is not None
    assert result.validation_fit_percent == pytest.approx(
        contiguous.validation_fit_percent, abs=1.0
    )
    assert pytest.approx(TRUTH.K, rel=0.01) == result.model.K


def test_split_just_after_a_gap_moves_back_to_the_gap():
    n = GAPPED.n_samples
    start = GAPPED.segment_starts[1]
    fraction = 1.0 - (start + 5) / n  # five samples into the third segment
    result = identify(GAPPED, IdentifyOptions(order=1, delay=0.4, validate_split=fraction))
    assert result.n_samples == start
    assert result.split_time == pytest.approx(GAPPED.segment_t0[1])


def test_step_ls_uses_rows_within_segments_only():
    N = 12
    work = decimate(GAPPED, 1.0)
    assert work.n_segments == 3
    est = StepResponseLS(N=N, delay=TRUTH.delay).fit(work)
    rows = sum(max(b - a - N, 0) for a, b in work.segment_bounds())
    assert est.n_rows_used_ <= rows
    ref = StepResponseLS(N=N, delay=TRUTH.delay).fit(decimate(FULL, 1.0))
    assert pytest.approx(ref.K_, rel=0.01) == est.K_
    assert pytest.approx(ref.T_, rel=0.03) == est.T_
    assert est.fit_percent_ == pytest.approx(ref.fit_percent_, abs=1.5)
    result = identify(
        GAPPED, IdentifyOptions(method="step-ls", delay=TRUTH.delay, N=N, validate_split=0.35)
    )
    assert result.to_json()["segments"] == 3
    assert result.validation_fit_percent is not None
    assert result.validation_fit_percent > 90.0


def test_lowpass_decimate_and_select_never_reach_across_a_gap():
    # two constant segments at very different levels: a filter run across the join would
    # smear one level into the other
    a = IOData(np.ones(300), np.zeros(300), 0.02)
    b = IOData(np.ones(300), np.full(300, 100.0), 0.02, t0=7.0)  # gap of 1.02 s
    joined = join_segments([a, b])
    filtered = lowpass(joined, 1.0)
    np.testing.assert_allclose(filtered.y[:300], 0.0, atol=1e-9)
    np.testing.assert_allclose(filtered.y[300:], 100.0, atol=1e-9)
    assert filtered.segment_starts == (300,)
    # decimation keeps the controller's one clock: changes every 1 s at t = k + 0.5
    t = np.r_[a.t, b.t]
    u = np.floor(t - 0.5)
    joined = IOData(u, u, 0.02, segment_starts=(300,), segment_t0=(7.0,))
    d = decimate(joined, 1.0)
    assert d.n_segments == 2
    assert d.sample_time == 1.0
    kept_t = d.t
    np.testing.assert_allclose((kept_t - 0.5) % 1.0, 0.0, atol=1e-9)
    np.testing.assert_array_equal(d.u, np.floor(kept_t - 0.5))
    # select on the true time axis: the window straddles the gap
    s = select(joined, 5.0, 8.0)
    assert s.n_segments == 2
    assert s.t[0] == pytest.approx(5.0)
    assert s.t[-1] == pytest.approx(7.98)


def test_residual_correlations_are_summed_within_segments():
    rng = np.random.default_rng(3)
    e = rng.normal(size=1000)
    starts = (400,)
    lags = np.arange(1, 6, dtype=float)
    r = _normalised_xcorr(e, e, lags, starts)
    d = e - e.mean()
    expected = [
        (d[k:400] @ d[: 400 - k] + d[400 + k :] @ d[400:-k]) / (1000 * d.std() ** 2)
        for k in range(1, 6)
    ]
    np.testing.assert_allclose(r, expected, rtol=1e-12)
    # small command changes within the segments, a large jump across the gap, and a
    # transient in the residual at the second segment's start (its initial state): counted
    # across the join, the jump would seem to cause the transient
    u = np.r_[
        np.repeat(rng.choice([1.0, 1.1], 20), 20)[:400],
        5.0 + np.repeat(rng.choice([1.0, 1.1], 30), 20),
    ]
    res = 0.01 * e
    res[400:420] += 0.5
    assert not input_residual_correlation(u, res).passed
    assert input_residual_correlation(u, res, segment_starts=starts).passed
    # a gap ends a plateau
    errs = steady_state_errors(np.ones(1000), 10.0 + e, 10.0 + e, 0.1, 5.0, starts)
    assert len(errs) == 2


def test_a_log_without_gaps_gives_the_same_numbers_through_join_segments():
    one = join_segments([FULL])
    assert one is FULL
    est = OutputError(order=1, delay=0.4).fit(FULL)
    assert est.n_segments_ == 1
    assert est.param_names_ == ("K", "T", "offset", "c0")
    assert math.isfinite(est.K_)


def test_step_ls_takes_its_initial_level_from_before_a_first_step_inside_a_gap():
    # the record's first command change falls inside a gap: the initial steady state is the
    # level before it, not an average reaching into the next plateau (found by a new user: K
    # was 11 % high and the fit 13 % on such a log)
    rng = np.random.default_rng(11)
    u = np.repeat([2.0, 3.0, 2.5, 1.5, 2.5, 3.0], 300)  # steps every 30 s at 0.1 s
    y = OFFSET + simulate_model(TRUTH, u, H) + rng.normal(0.0, SIGMA, u.size)
    step = 300
    keep = np.ones(u.size, dtype=bool)
    keep[step - 1 : step + 1] = False  # the samples around the first step are missing
    t = H * np.arange(u.size)
    gapped = IOData(
        u[keep], y[keep], H, segment_starts=(step - 1,), segment_t0=(float(t[step + 1]),)
    )
    # at the 1 s control period, as the procedure runs it: N = 12 s covers the settling time
    whole = StepResponseLS(N=12, delay=TRUTH.delay).fit(decimate(IOData(u, y, H), 1.0))
    split = StepResponseLS(N=12, delay=TRUTH.delay).fit(decimate(gapped, 1.0))
    gain, gain_whole = split.K_, whole.K_
    assert split.offset_ == pytest.approx(whole.offset_, abs=3 * SIGMA)
    assert gain == pytest.approx(gain_whole, rel=0.01)
    assert gain == pytest.approx(TRUTH.K, rel=0.02)
