"""Long records (issue 38, second round): a covariance only where the order rule reads one.

On a long record the order BIC prefers is stored (its Jacobian, colour test and covariance);
another order is stored only when the rule keeps it. The rule and the kept order's numbers are
those of a fit of that order alone; the order not needed says its standard errors were not
computed. Here the rule runs on 40,000 samples with the thresholds lowered.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.identify import OutputError
from fuelid.identify import _long_record as long_record
from fuelid.io.timeseries import IOData
from fuelid.model import MODEL_KEYS, ProcessModel, simulate_model

H = 0.02


def _record(model: ProcessModel, seed: int) -> IOData:
    """40,000 samples at 50 Hz: steps every 10 s among four levels, white noise."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([1.0, 1.5, 2.0, 2.5], 80), 500)
    y = 14.0 + simulate_model(model, u - u[0], H) + rng.normal(0.0, 0.1, u.size)
    return IOData(u, y, H)


@pytest.fixture
def long_rule(monkeypatch: pytest.MonkeyPatch) -> None:
    """The long-record rule for records over 30,000 samples, searched on 12,000."""
    monkeypatch.setattr(long_record, "LONG_RECORD", 30_000)
    monkeypatch.setattr(long_record, "SEARCH_SAMPLES", 12_000)


@pytest.mark.parametrize(
    ("model", "kept"),
    [
        (ProcessModel(K=13.5, T=1.2, T2=0.3, delay=0.26), 2),
        (ProcessModel(K=13.5, T=1.2, delay=0.26), 1),
    ],
)
def test_only_the_orders_the_rule_needs_get_a_covariance(
    long_rule: None, model: ProcessModel, kept: int
) -> None:
    data = _record(model, seed=kept)
    est = OutputError(order="auto", full_record=True).fit(data)
    alone = OutputError(order=kept, full_record=True).fit(data)  # one order: stored as it is fitted
    choice = est.order_choice_
    assert choice.chosen == kept
    by_order = {c.order: c for c in choice.candidates}
    assert by_order[kept].stderr_computed
    other = by_order[3 - kept]
    # BIC preferred the kept order: the other one's covariance was never needed
    assert not other.stderr_computed
    assert all(value is None for value in other.stderr.values())
    assert other.to_json(choice.chosen_candidate.bic)["stderr_computed"] is False
    # the kept order's numbers are those of a fit of that order alone (its Jacobian's lag
    # columns by finite differences when it is stored after the other order was searched,
    # not the polish's own: the same to 1e-9)
    for name in MODEL_KEYS:
        assert getattr(est, f"{name}_") == getattr(alone, f"{name}_")
        expected = alone.stderr_[name]
        assert est.stderr_[name] == (
            None if expected is None else pytest.approx(expected, rel=1e-6)
        )
    assert est.fit_percent_ == pytest.approx(alone.fit_percent_, rel=1e-12)
    assert est.covariance_ == alone.covariance_
