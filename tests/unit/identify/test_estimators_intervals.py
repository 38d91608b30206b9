"""95 % intervals that respect the bounds of the parameters (identify's ``ci95``).

A positive parameter (T, T2, the delay) gets the delta-method interval of its logarithm,
exp(ln p ± 1.96·se/p); K, which may have either sign, the symmetric p ± 1.96·se. The normal
interval of a delay whose standard error exceeds delay/1.96 reaches below zero; the log interval
does not.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuelid.identify import IdentifyOptions, identify, interval95
from fuelid.io.timeseries import IOData
from fuelid.model import Z95, ProcessModel, simulate_model


def test_log_interval_of_a_positive_parameter_is_exp_of_the_log_interval():
    value, se = 0.05, 0.1  # se > value/1.96: the normal interval would start at −0.146
    (low, high), method = interval95(value, se, positive=True) or ([], "")
    assert method == "log"
    assert low == pytest.approx(value * math.exp(-Z95 * se / value), rel=1e-12)
    assert high == pytest.approx(value * math.exp(Z95 * se / value), rel=1e-12)
    assert 0.0 < low < value < high
    # symmetric on the log scale: the estimate is the geometric mean of the bounds
    assert math.sqrt(low * high) == pytest.approx(value, rel=1e-12)


def test_gain_keeps_the_symmetric_interval_and_may_be_negative():
    (low, high), method = interval95(-0.3, 0.2) or ([], "")
    assert method == "normal"
    assert (low, high) == (pytest.approx(-0.3 - Z95 * 0.2), pytest.approx(-0.3 + Z95 * 0.2))
    assert interval95(1.0, None) is None
    assert interval95(1.0, math.nan, positive=True) is None


def test_delay_at_its_bound_gets_a_clipped_interval():
    # ln 0 is undefined; a log interval that overflows is no interval either
    for value in (0.0, 1e-30):
        (low, high), method = interval95(value, 0.7, positive=True) or ([], "")
        assert method == "clipped"
        assert low == 0.0
        assert high == pytest.approx(value + Z95 * 0.7)


def test_identified_delay_interval_stays_positive_when_the_delay_is_poorly_determined():
    # a 0.05 s delay (half a sample) under heavy noise: se(delay) > delay/1.96, so the old
    # estimate ± 1.96·se interval reached below zero
    truth = ProcessModel(K=2.0, T=1.0, delay=0.05)
    rng = np.random.default_rng(0)
    u = np.repeat(np.r_[0.0, rng.choice([0.0, 1.0], 11)], 100)
    y = 5.0 + simulate_model(truth, u, 0.1) + rng.normal(0.0, 0.2, u.size)
    result = identify(IOData(u=u, y=y, sample_time=0.1), IdentifyOptions(order=1, delay="auto"))
    delay, se = result.model.delay, result.stderr["delay"]
    assert se is not None
    assert delay > 0.0
    assert se > delay / Z95  # the case in question
    ci = result.ci95()
    methods = result.ci95_method()
    low, high = ci["delay"] or [math.nan, math.nan]
    assert methods["delay"] == "log"
    assert 0.0 < low < delay < high
    assert low == pytest.approx(delay * math.exp(-Z95 * se / delay), rel=1e-12)
    # T: log interval; K: symmetric; fixed parameters: none, and no method
    assert methods == {"K": "normal", "T": "log", "T2": None, "T_f": None, "delay": "log"}
    assert ci["T2"] is None
    K, se_K = result.model.K, result.stderr["K"] or math.nan
    assert ci["K"] == [pytest.approx(K - Z95 * se_K), pytest.approx(K + Z95 * se_K)]
    assert result.to_json()["ci95_method"] == methods
