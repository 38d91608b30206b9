"""The K(T) tracker follows fuelid's estimator conventions.

Settings in ``__init__``, ``fit`` returns self, fitted attributes (ending in ``_``) only after
a fit that succeeded.
"""

from __future__ import annotations

import pytest

from fuelid.errors import NotFittedError
from fuelid.online import GainObservation, KTracker, TrackingError

FITTED = ("observations_", "mode_", "fit_", "bands_")


def _obs(i: int, T_C: float) -> GainObservation:
    return GainObservation(60.0 * i, T_C, 3.0, 11.7, 0.1, 13.0)


def test_settings_are_kept_and_fitted_attributes_absent_before_fit() -> None:
    tracker = KTracker(forgetting_time_s=3600.0, max_observations=5)
    assert tracker.get_params() == {
        "k_plant": None,
        "forgetting_time_s": 3600.0,
        "min_spread_C": 2.0,
        "band_width_V": 1.0,
        "max_observations": 5,
    }
    assert repr(tracker).startswith("KTracker(k_plant=None, forgetting_time_s=3600.0")
    for name in FITTED:
        assert not hasattr(tracker, name)
        with pytest.raises(NotFittedError, match=name):
            getattr(tracker, name)
    with pytest.raises(NotFittedError):
        tracker.predict(20.0)


def test_fit_returns_self_with_every_fitted_attribute() -> None:
    tracker = KTracker()
    assert tracker.fit([_obs(0, 0.0), _obs(1, 10.0)]) is tracker
    assert all(hasattr(tracker, name) for name in FITTED)
    assert tracker.mode_ == "ratio"


def test_a_refused_fit_leaves_the_tracker_unfitted_and_keeps_the_observations() -> None:
    tracker = KTracker().fit([_obs(0, 0.0), _obs(1, 10.0)])
    with pytest.raises(TrackingError, match="at least 2"):
        tracker.fit([_obs(2, 20.0)])
    assert not any(hasattr(tracker, name) for name in FITTED)
    assert tracker.observations == (_obs(2, 20.0),)


def test_update_builds_on_the_observations_held() -> None:
    tracker = KTracker(max_observations=3)
    with pytest.raises(TrackingError):
        tracker.update(_obs(0, 0.0))  # one window alone is not tracked
    assert tracker.update(_obs(1, 10.0)) is tracker  # the second is, with the first
    assert len(tracker.observations_) == 2
    for i in range(2, 6):
        tracker.update(_obs(i, 10.0 * i))
    assert [o.time for o in tracker.observations_] == [180.0, 240.0, 300.0]
    assert tracker.observations == tuple(tracker.observations_)
