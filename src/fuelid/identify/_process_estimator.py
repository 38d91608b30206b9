"""What the estimators fitted as the output-error regression share: oe's and pem's process part.

:class:`~fuelid.identify._oe.OutputError` and :class:`~fuelid.identify._pem.PredictionError` fit
the same process model, ŷ = b + K·s(T, T2, θ) + Σ c_i·p_i^k
(:mod:`fuelid.identify._variable_projection`), pem with a noise model beside it. So the fitted
model, its free run, its python-control form and the parameters' correlation are the same code
for both, here; what differs (the search, the covariance, pem's prediction) stays in each.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fuelid.identify._base import Estimator, Initial
from fuelid.identify._segments import offset_and_free_responses
from fuelid.identify._variable_projection import Structure, continue_fitted, solve_linear
from fuelid.io.timeseries import FloatArray, IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel
from fuelid.numerics_mode import Numerics

if TYPE_CHECKING:
    import control


class ProcessModelEstimator(Estimator):
    """Base of oe and pem: the fitted process model and everything read off it alone.

    A subclass sets the fitted attributes below in ``fit``, stores its constructor's
    ``numerics`` and says which regression state it fitted (:meth:`_fitted_regression`).
    """

    K_: float
    T_: float
    T2_: float
    delay_: float
    T_f_: float
    offset_: float
    u_ref_: float
    cov_: FloatArray
    n_samples_: int
    numerics: Numerics

    @property
    def model_(self) -> ProcessModel:
        """The fitted process model (K in output unit per input unit, times in s)."""
        return ProcessModel(K=self.K_, T=self.T_, T2=self.T2_, T_f=self.T_f_, delay=self.delay_)

    def simulate(self, data: IOData, initial: Initial = "fitted") -> FloatArray:
        """Free-run output of the fitted process model for the input ``data.u`` [output unit].

        A noise model (pem's) plays no part: this is G·u plus the offset and initial state.

        Parameters
        ----------
        data : IOData
            The record; any sample time (the model is continuous-time). ``data.y`` is used only
            by ``initial="estimate"``.
        initial : "fitted", "rest" or "estimate"
            The state at the record's first sample:

            - ``"fitted"`` (default): the initial state, offset and reference input estimated by
              ``fit``. Valid only on the fitting record or on one that continues it (the whole
              log after fitting its first part: the held-out rest is then scored honestly, as
              ``fuelid identify --validate-split`` does); anything else is refused. This is
              what ``fit_percent_`` scores.
            - ``"rest"``: at rest at u[0] before the record, the output at the fitted offset
              ``offset_ + K_·(u[0] − u_ref_)``. What a separate validation record is scored
              with (``--validate-file``).
            - ``"estimate"``: the offset and the free-response amplitudes of every lag
              (c_i·e^(−k·h/T_i)) re-estimated by least squares on ``data``; for held-out
              records that do not start at rest.

        Returns
        -------
        ndarray
            ŷ, one value per sample.
        """
        self._check_simulation(data, initial)
        u, h = data.u, data.sample_time
        bounds = data.segment_bounds()
        if initial == "fitted":
            return self._continue_fitted(data)
        discrete = discretise(self.model_.time_constants, self.delay_, h, self.numerics)
        # every segment from rest at its own first command: nothing runs across a gap
        response = np.empty(u.size)
        for a, b in bounds:
            response[a:b] = self.K_ * discrete.response(u[a:b] - float(u[a]))
            if initial == "rest":
                response[a:b] += self.offset_ + self.K_ * (float(u[a]) - self.u_ref_)
            elif a:  # a later segment's level relative to the first: one offset for all
                response[a:b] += self.K_ * (float(u[a]) - float(u[0]))
        if initial == "rest":
            return response
        # one offset for the record, one free response per segment
        basis = offset_and_free_responses(discrete, bounds)
        free = solve_linear(basis, data.y - response).beta
        return np.asarray(response + basis @ free, dtype=float)

    def _continue_fitted(self, data: IOData) -> FloatArray:
        """``simulate(data, "fitted")``: the fitted states, and new ones after later gaps.

        The segments of the fitting record (the last one continued to its end in ``data``) use
        the offset and initial states the fit estimated. A segment that begins after the
        fitting record (a gap in a held-out part) has no fitted state: it starts from rest at
        its first command, plus a free response estimated by least squares on its own samples
        (``initial="estimate"`` of the fit's settings; none for "rest"), the offset kept.
        """
        st, beta = self._fitted_regression()
        return continue_fitted(
            st, beta, self.model_, self.u_ref_, self.n_samples_, data, self.numerics
        )

    def _fitted_regression(self) -> tuple[Structure, FloatArray]:
        """The structure and the linear parameters (K, offset, initial states) of the free run."""
        raise NotImplementedError

    def to_control(self) -> control.TransferFunction:
        """Delay-free process part as a :class:`control.TransferFunction` (delay in ``delay_``)."""
        return self.model_.to_control()

    @property
    def correlation_(self) -> FloatArray:
        """Correlation matrix of the estimated parameters (order of ``param_names_``)."""
        sd = np.sqrt(np.diag(self.cov_))
        return np.asarray(self.cov_ / np.outer(sd, sd), dtype=float)


__all__ = ["ProcessModelEstimator"]
