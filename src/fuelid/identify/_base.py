"""The estimator convention every fuelid estimator follows (described in :mod:`fuelid.identify`).

:class:`Estimator` holds what the convention needs once: settings as parameters
(:meth:`~Estimator.get_params`, :meth:`~Estimator.set_params`, the ``repr``), fitted attributes
that do not exist before ``fit`` (:class:`~fuelid.errors.NotFittedError`), the check of the
``initial`` condition of a simulation and of the record ``initial="fitted"`` refers to, and
:meth:`~Estimator.score`.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal, get_args

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError, NotFittedError
from fuelid.io.timeseries import IOData
from fuelid.model import nrmse_fit
from fuelid.params import Params

FloatArray = NDArray[np.float64]
Initial = Literal["rest", "estimate", "fitted"]
"""Initial condition of a simulation (see :meth:`Estimator.simulate`)."""
INITIAL_CONDITIONS: tuple[str, ...] = get_args(Initial)


def _digest(u: FloatArray) -> str:
    return hashlib.blake2b(
        np.ascontiguousarray(u, dtype=float).tobytes(), digest_size=16
    ).hexdigest()


@dataclass(frozen=True)
class _Record:
    """Fingerprint of the input a model was fitted on: what ``initial="fitted"`` refers to."""

    n_samples: int
    sample_time: float
    digest: str
    segment_starts: tuple[int, ...] = ()

    @classmethod
    def of(cls, data: IOData) -> _Record:
        return cls(data.n_samples, data.sample_time, _digest(data.u), data.segment_starts)

    def mismatch(self, data: IOData) -> str | None:
        """Why ``data`` does not start with this record (None when it does)."""
        if not math.isclose(data.sample_time, self.sample_time, rel_tol=1e-9):
            return f"is sampled every {data.sample_time:g} s"
        if data.n_samples < self.n_samples:
            return f"has only {data.n_samples} samples"
        if _digest(data.u[: self.n_samples]) != self.digest:
            return "does not start with the fitting record's input"
        if tuple(i for i in data.segment_starts if i < self.n_samples) != self.segment_starts:
            return "has its gaps elsewhere than the fitting record"
        return None


class Estimator(Params):
    """Base of the estimators: settings, fitted state, initial conditions, score.

    A subclass lists its constructor's parameters in ``_SETTINGS``, stores them unchanged in
    ``__init__``, fits inside ``with self._fitting(data):`` and implements :meth:`simulate`.
    """

    _SETTINGS: ClassVar[tuple[str, ...]] = ()

    # ------------------------------------------------------------------ settings
    # ------------------------------------------------------------------ fitted state
    @contextmanager
    def _fitting(self, data: IOData) -> Iterator[None]:
        """Forget any previous fit, run the body, and mark the estimator fitted on ``data``.

        If the body raises, the estimator is left unfitted (no half-set attributes).
        """
        self._unfit()
        try:
            yield
        except BaseException:
            self._unfit()
            raise
        self._fit_record = _Record.of(data)

    def _unfit(self) -> None:
        for name in [n for n in vars(self) if n not in self._SETTINGS]:
            delattr(self, name)

    def _check_fitted(self) -> None:
        if "_fit_record" not in vars(self):
            raise NotFittedError(f"{type(self).__name__} is not fitted: call fit(data) first")

    if not TYPE_CHECKING:  # hidden from mypy, which would otherwise accept any attribute name

        def __getattr__(self, name: str) -> Any:
            # called only when normal lookup fails: a fitted attribute before fit
            if name.endswith("_") and not name.startswith("__"):
                raise NotFittedError(
                    f"{type(self).__name__} is not fitted: {name} exists only after fit(data)"
                )
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    # ------------------------------------------------------------------ simulation
    def _check_simulation(self, data: IOData, initial: str) -> None:
        """Fitted, a known ``initial``, and for "fitted" a record that starts with the fit's."""
        self._check_fitted()
        if initial not in INITIAL_CONDITIONS:
            raise FuelidError(
                f"initial must be one of {', '.join(map(repr, INITIAL_CONDITIONS))}, got "
                f"{initial!r}"
            )
        if initial == "fitted":
            record: _Record = self._fit_record
            reason = record.mismatch(data)
            if reason is not None:
                raise FuelidError(
                    "initial='fitted' is the initial state estimated on the fitting record "
                    f"({record.n_samples} samples every {record.sample_time:g} s) and holds only "
                    f"for that record or one that continues it; this one {reason}: use "
                    "initial='estimate' (or 'rest') on other data"
                )

    @staticmethod
    def _check_horizon(horizon: int) -> None:
        if isinstance(horizon, bool) or not isinstance(horizon, int | np.integer) or horizon < 1:
            raise FuelidError(f"horizon must be a whole number of samples ≥ 1, got {horizon!r}")

    def simulate(self, data: IOData, initial: Initial = "fitted") -> FloatArray:
        """Free-run output of the fitted model for ``data.u`` (implemented by each estimator)."""
        raise NotImplementedError

    def score(self, data: IOData, initial: Initial = "fitted") -> float:
        """NRMSE fit [%] of :meth:`simulate` on ``data``: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖).

        ``initial`` as for :meth:`simulate`; the default scores the fitting record (or one that
        continues it, as a validation split does); use ``"estimate"`` on other records.
        """
        return nrmse_fit(data.y, self.simulate(data, initial))
