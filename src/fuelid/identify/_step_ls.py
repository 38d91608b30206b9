r"""The source article's method: truncated step-response least squares, then K and T by Newton.

Stage 1 (docs/explanation/identification.md §2.1). The input is held between control periods, so it
is a sum of steps; with the unit step response sampled at the control period, :math:`a_i =
s(i\,T_s)`, and N chosen so that the response has settled after N periods (:math:`a_i = a_N` for i ≥
N), superposition gives, in deviations from the initial steady state,

.. math:: y(k) = \sum_{i=1}^{N-1} a_i\,\Delta u(k-i) + a_N\,u(k-N) + e(k),
          \qquad \Delta u(k) = u(k) - u(k-1),

for the rows k = N … n−1 (each needs N past inputs). The rows are stacked into
:math:`Y = \Phi\theta + e`, :math:`\theta = [a_1 \dots a_N]^T`, and solved by least squares.

Stage 2 (:mod:`fuelid.identify._step_shape_fit`). The model step response with the flowmeter's
T_f and dead time τ known,

.. math:: s(t) = K\left[1 - \frac{T e^{-t'/T} - T_f e^{-t'/T_f}}{T - T_f}\right],
          \qquad t' = t - \tau \;(s = 0 \text{ for } t' \le 0),

is fitted to :math:`\hat a_i` at :math:`t_i = i\,T_s` (K(1 − e^(−t'/T)) when T_f = 0, and the
repeated-root limit when T → T_f). K enters linearly and is eliminated in closed form for each T;
T solves the nonlinear normal equation of the concentrated cost by a safeguarded Newton
iteration.

Choices made here (the article's equations are lost; docs/explanation/identification.md §2.1 records
these):

- **Deviations.** u is taken relative to ``u0 = u[0]`` and y relative to ``y0``, the mean of y
  over the samples up to and including the first input change (the output cannot react at the
  sample where the input changes: a_0 = s(0) = 0). The record must start at rest; the plant is
  assumed to have been at rest at u0 before it (Δu = 0 before the record).
- **Rows used.** Every row k = N … n−1 whose regressor is not identically zero. Rows with some
  input change in their window (the *exciting* rows) inform a_1 … a_{N−1}; steady rows after a
  change, [0 … 0, u(k−N) − u0], are exact equations for a_N (the static gain) and are kept.
  Only all-zero rows (steady at u0) are dropped: they carry no information on θ. Both counts
  are reported (``n_rows_used_``, ``n_exciting_rows_``).
- **Refusal.** :class:`~fuelid.errors.NotExcitingError` with the reason when the input is
  constant, the record is too short, rank(Φ) < N (the unexcited coefficients are named) or the
  condition number of Φ exceeds ``max_condition``.
- **Records with gaps** (:mod:`fuelid.identify._segments`): a row k is used only when its
  N past inputs lie in the same segment as k (rows k = a+N … b−1 of a segment a:b), so no row
  spans a gap; the deviations are from the one initial steady state of the first segment (one
  plant, one offset). A segment of N samples or fewer gives no row (a warning says so). The
  simulation restarts each later segment at rest at its first command (``"fitted"`` adds the
  free response of its initial state, fitted on the segment).
- **Known weakness** (measured, docs/explanation/identification.md §2.4): if the true response has
  not settled at N·T_s, the truncation biases a_N and hence K and T whatever the noise level; a
  warning is issued when the fitted model's 98 % settling time exceeds N·T_s.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Self

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from fuelid.errors import FuelidError, NotExcitingError
from fuelid.identify._base import Estimator, Initial
from fuelid.identify._segments import offset_and_free_responses, state_from_first_samples
from fuelid.identify._step_shape_fit import _MAX_ITER, fit_step_shape, step_shape
from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel

if TYPE_CHECKING:
    import control

__all__ = ["StepResponseLS", "step_shape"]

FloatArray = NDArray[np.float64]

#: N above which the method is warned to be a poor fit for the sample time
_MANY_COEFFICIENTS = 60


class StepResponseLS(Estimator):
    r"""The article's two-stage estimator of K·e^(−τs)/((T s+1)(T_f s+1)), T_f and τ known.

    Parameters
    ----------
    N : int or None
        Number of step-response coefficients (the response must have settled after N·T_s).
    T_f : float
        Flowmeter time constant [s], a fixed prior (0: first-order model).
    delay : float
        Dead time τ [s], a fixed prior.
    settling_time : float or None
        98 % settling time of a prior model [s] (e.g. the plant TOML's); used for
        ``N = ceil(settling_time / T_s)`` when N is not given.
    max_condition : float
        Largest accepted condition number of the regressor matrix Φ (above it the input
        changes do not separate the N coefficients and the fit is refused).

    Attributes
    ----------
    a_, a_stderr_ : ndarray
        Step-response coefficients a_1 … a_N [output unit / input unit] and their standard errors.
    cov_a_ : ndarray
        Covariance σ²(ΦᵀΦ)⁻¹ of ``a_`` (NaN when the rows leave no degree of freedom).
    K_, T_ : float
        Fitted static gain [output unit / input unit] and time constant [s].
    T2_ : float
        0: the method fits one process time constant.
    K_stderr_, T_stderr_ : float
        Their standard errors, ``cov_a_`` propagated through the stage-2 fit (linearised).
    stderr_ : dict
        The same by model parameter K, T, T2, delay, T_f (None for the fixed ones).
    fixed_ : tuple of str
        The model parameters held fixed: T2, delay, T_f.
    T_f_, delay_ : float
        The priors used [s].
    N_ : int
        Number of coefficients used.
    offset_, u0_ : float
        Output and input at the initial steady state (deviations are taken from these).
    n_rows_used_, n_exciting_rows_ : int
        Regression rows used, and how many of them contain an input change in their window.
    condition_number_ : float
        Condition number of the regressor matrix.
    residual_std_ : float
        Standard deviation of the stage-1 residuals [output unit].
    fit_rms_ : float
        RMS of â − s(t_i) in stage 2 [output unit / input unit].
    newton_iterations_ : int
        Newton iterations of stage 2.
    model_ : ProcessModel
        The fitted model.
    fit_percent_ : float
        NRMSE fit [%] of ``simulate(data, initial="fitted")`` on the fitting record.
    n_samples_, sample_time_ : int, float
        Size and sample time [s] of the fitting record.
    warnings_ : list of str
        The data's notes, then what the fit noticed (truncation bias, …).

    Examples
    --------
    >>> from fuelid.model import ProcessModel
    >>> u = np.repeat([0.0, 1.0, 0.0, 2.0, 1.0], 10)
    >>> s = ProcessModel(K=2.0, T=1.5).step_response(np.arange(50.0))
    >>> y = 5.0 + np.convolve(np.diff(u, prepend=0.0), s)[:50]
    >>> est = StepResponseLS(N=20).fit(IOData(u=u, y=y, sample_time=1.0))
    >>> round(est.K_, 4), round(est.T_, 4), est.warnings_
    (2.0, 1.5, [])
    """

    _SETTINGS = ("N", "T_f", "delay", "settling_time", "max_condition")

    a_: FloatArray
    a_stderr_: FloatArray
    cov_a_: FloatArray
    K_: float
    T_: float
    T2_: float
    K_stderr_: float
    T_stderr_: float
    stderr_: dict[str, float | None]
    fixed_: tuple[str, ...]
    T_f_: float
    delay_: float
    N_: int
    offset_: float
    u0_: float
    n_rows_used_: int
    n_exciting_rows_: int
    condition_number_: float
    residual_std_: float
    fit_rms_: float
    newton_iterations_: int
    model_: ProcessModel
    fit_percent_: float
    n_samples_: int
    sample_time_: float
    warnings_: list[str]

    def __init__(
        self,
        *,
        N: int | None = None,
        T_f: float = 0.0,
        delay: float = 0.0,
        settling_time: float | None = None,
        max_condition: float = 1e8,
    ) -> None:
        self.N = N
        self.T_f = T_f
        self.delay = delay
        self.settling_time = settling_time
        self.max_condition = max_condition

    # ------------------------------------------------------------------ public API
    def fit(self, data: IOData) -> Self:
        """Estimate a_1 … a_N by least squares, then K and T from them.

        Parameters
        ----------
        data : IOData
            A record at the control period (e.g. 1 s), starting at rest.

        Returns
        -------
        StepResponseLS
            ``self``, with the fitted attributes (ending in ``_``) set.

        Raises
        ------
        NotExcitingError
            The input does not excite all N coefficients (the reason is in the message).
        FuelidError
            Bad settings (no N and no settling time, negative priors, …).
        """
        with self._fitting(data):
            self._fit(data)
        self.fit_percent_ = self.score(data, initial="fitted")
        return self

    def simulate(self, data: IOData, initial: Initial = "fitted") -> FloatArray:
        """Free-run output of the fitted model for the input ``data.u`` [output unit].

        Uses the truncated step-response (FIR) form of the regression with the coefficients
        s_i = s(i·T_s), i = 1 … N, of the fitted model (:func:`step_shape`):
        ŷ(k) = y_rest + Σ_{i<N} s_i Δu(k−i) + s_N (u(k−N) − u_rest).

        Parameters
        ----------
        data : IOData
            Record at the sample time of the fit; ``data.y`` is used only by
            ``initial="estimate"``.
        initial : "fitted", "rest" or "estimate"
            The state at the record's first sample:

            - ``"fitted"`` (default): what ``fit`` assumed, at rest at ``u0_`` with the output
              at ``offset_``. Valid only on the fitting record or one that continues it
              (refused otherwise); there it equals ``"rest"``. What ``fit_percent_`` scores.
            - ``"rest"``: at rest at u[0] before the record, y_rest = ``offset_`` +
              ``K_``·(u[0] − ``u0_``) (u_rest = u[0]). What a separate validation record is
              scored with (``--validate-file``).
            - ``"estimate"``: from rest at u[0], plus an offset and the free response
              c_i·e^(−k·T_s/T_i) of the fitted model's lags, estimated by least squares on
              ``data``: for records that do not start at rest.

        Returns
        -------
        ndarray
            ŷ, one value per sample.
        """
        self._check_simulation(data, initial)
        if not math.isclose(data.sample_time, self.sample_time_, rel_tol=1e-9):
            raise FuelidError(
                f"simulate needs data at the fitted sample time {self.sample_time_:g} s, got "
                f"{data.sample_time:g} s"
            )
        s = self.K_ * step_shape(
            self.sample_time_ * np.arange(self.N_ + 1, dtype=float), self.T_, self.T_f_, self.delay_
        )
        s[0] = 0.0
        impulse = np.concatenate(([0.0], np.diff(s)))  # h_0 = 0, h_i = s_i − s_{i−1}
        u = data.u
        bounds = data.segment_bounds()
        if len(bounds) > 1:
            return self._simulate_segments(data, initial, impulse)
        u_rest = self.u0_ if initial == "fitted" else float(u[0])
        response = np.convolve(u - u_rest, impulse)[: data.n_samples]
        if initial != "estimate":
            return np.asarray(self.offset_ + self.K_ * (u_rest - self.u0_) + response, dtype=float)
        modes = discretise(self.model_.time_constants, self.delay_, self.sample_time_).modes(u.size)
        basis = np.column_stack((np.ones(u.size), modes))
        coefficients = np.linalg.lstsq(basis, data.y - response, rcond=None)[0]
        return np.asarray(response + basis @ coefficients, dtype=float)

    def _simulate_segments(self, data: IOData, initial: Initial, impulse: FloatArray) -> FloatArray:
        """:meth:`simulate` of a record with gaps: each segment from rest at its first command.

        The first segment starts as for a contiguous record. With ``"fitted"`` a later segment
        starts from the state its own first samples show, as the fit takes the record's
        initial steady state from the samples before its first change: until the segment's
        first command change reaches the output, the output is the level and free response
        of that state, fitted by least squares on those samples
        (:func:`~fuelid.identify._segments.state_from_first_samples`). The regression used no
        sample within N of a segment's start, so the fit has no state there to continue from;
        holding the fit's level instead put a dip at every restart where the model's level was
        off the measured one (the free response's least squares overshoots a constant error).
        When those samples are too few, the free response (the lags' modes) is fitted on the
        whole segment with the offset held. With ``"estimate"`` one offset for the record and
        one free response per segment are fitted.
        """
        u = data.u
        bounds = data.segment_bounds()
        discrete = discretise(self.model_.time_constants, self.delay_, self.sample_time_)
        y_hat = np.empty(u.size)
        for j, (a, b) in enumerate(bounds):
            u_rest = self.u0_ if (j == 0 and initial == "fitted") else float(u[a])
            response = np.convolve(u[a:b] - u_rest, impulse)[: b - a]
            restart = (
                state_from_first_samples(discrete, data.y[a:b], response)
                if j and initial == "fitted"
                else None
            )
            if restart is not None:
                y_hat[a:b] = response + restart
                continue
            y_hat[a:b] = response
            if initial != "estimate":
                y_hat[a:b] += self.offset_ + self.K_ * (u_rest - self.u0_)
            elif j:  # a later segment's level relative to the first: one offset for all
                y_hat[a:b] += self.K_ * (u_rest - float(u[0]))
            if j and initial == "fitted":
                modes = discrete.modes(b - a)
                c = np.linalg.lstsq(modes, data.y[a:b] - y_hat[a:b], rcond=None)[0]
                y_hat[a:b] += modes @ c
        if initial != "estimate":
            return y_hat
        basis = offset_and_free_responses(discrete, bounds)
        coefficients = np.linalg.lstsq(basis, data.y - y_hat, rcond=None)[0]
        return np.asarray(y_hat + basis @ coefficients, dtype=float)

    def predict(self, data: IOData, horizon: int = 1, initial: Initial = "rest") -> FloatArray:
        """k-step-ahead prediction ŷ(t | t − k) of the output, k = ``horizon`` [output unit].

        The regression's error is white and added to the output (noise model H = 1), so the
        k-step-ahead predictor is the free-run simulation for every k ≥ 1 (Ljung, *System
        Identification*, 2nd ed., 1999, §3.2): this returns ``simulate(data, initial)``;
        ``horizon`` is checked and otherwise has no effect. ``initial`` defaults to ``"rest"``
        (the record starts at rest at its first input).
        """
        self._check_horizon(horizon)
        return self.simulate(data, initial)

    def to_control(self) -> control.TransferFunction:
        """Delay-free part as a :class:`control.TransferFunction` (dead time in ``delay_``)."""
        return self.model_.to_control()

    # ------------------------------------------------------------------ internals
    def _fit(self, data: IOData) -> None:
        """Stage 1 (the coefficients and their covariance), then stage 2 and the checks."""
        T_s = float(data.sample_time)
        N = self._resolve_N(T_s)
        self._validate(N, T_s)
        self.warnings_ = list(data.notes)
        u, y = data.u, data.y
        n = u.size
        du = np.diff(u)
        # first sample of the segment each sample belongs to: a row k is used only when its
        # window k−N … k lies in one segment (never across a gap)
        bounds = data.segment_bounds()
        segment_start = np.repeat([a for a, _ in bounds], [b - a for a, b in bounds])
        within = segment_start[1:] < np.arange(1, n)  # du[j] = u[j+1] − u[j] inside a segment
        changes = np.flatnonzero((du != 0.0) & within)
        if changes.size == 0:
            raise NotExcitingError(
                f"input is constant over the record (no input change): the N={N} step-response "
                "coefficients are not identifiable; log a record with input steps"
            )
        if len(bounds) > 1:
            rows = sum(max(b - a - N, 0) for a, b in bounds)
            if rows < N:
                raise NotExcitingError(
                    f"record too short: its {len(bounds)} segments give {rows} regression rows "
                    f"within segments, fewer than N={N} coefficients"
                )
            barren = [f"{j + 1} ({b - a} samples)" for j, (a, b) in enumerate(bounds) if b - a <= N]
            if barren:
                self.warnings_.append(
                    f"segment {', '.join(barren)} of {len(bounds)} has no more than N={N} "
                    "samples: no regression row fits inside it, so it does not inform the fit"
                )
        elif n - N < N:
            raise NotExcitingError(
                f"record too short: {n} samples give {max(n - N, 0)} regression rows, fewer than "
                f"N={N} coefficients"
            )
        # deviations from the initial steady state (samples 0 … first change, inclusive)
        self.u0_ = float(u[0])
        # the steady state before the first change of the input anywhere, a change across a
        # gap included (it moves the level even though no row spans it), within segment 1
        first_change = int(np.flatnonzero(du != 0.0)[0])
        self.offset_ = float(np.mean(y[: min(first_change + 2, bounds[0][1])]))
        ud = u - self.u0_
        yd = y - self.offset_

        # Φ rows k = N … n−1: [Δu(k−1) … Δu(k−N+1), u(k−N)]; Δu(j) = du[j−1]
        window = sliding_window_view(du, N - 1)[: n - N, ::-1]
        phi = np.column_stack((window, ud[: n - N]))
        target = yd[N:]
        inside = segment_start[N:] <= np.arange(n - N)  # row k = N + i starts at sample i
        active = np.any(phi != 0.0, axis=1) & inside
        exciting = np.any(window != 0.0, axis=1) & inside
        phi, target = phi[active], target[active]
        self.n_rows_used_ = int(active.sum())
        self.n_exciting_rows_ = int(exciting.sum())
        if phi.shape[0] < N:
            self._check_excitation(phi, N, changes.size, np.zeros(0))  # refused: too few rows
        U, sv, Vt = np.linalg.svd(phi, full_matrices=False)
        self._check_excitation(phi, N, changes.size, sv)  # the fit's own singular values
        self.condition_number_ = float(sv[0] / sv[-1])
        a = Vt.T @ ((U.T @ target) / sv)
        resid = target - phi @ a
        dof = self.n_rows_used_ - N
        if dof > 0:
            sigma2 = float(resid @ resid) / dof
            self.cov_a_ = sigma2 * (Vt.T / sv**2) @ Vt
            self.residual_std_ = math.sqrt(sigma2)
        else:
            self.cov_a_ = np.full((N, N), np.nan)
            self.residual_std_ = math.nan
            self.warnings_.append(
                f"{self.n_rows_used_} rows for N={N} coefficients: no residual degree of "
                "freedom, standard errors unavailable"
            )
        self.a_ = a
        self.a_stderr_ = np.sqrt(np.diag(self.cov_a_))
        self.N_, self.sample_time_ = N, T_s
        self.T_f_, self.delay_ = float(self.T_f), float(self.delay)

        self.n_samples_ = n
        self._fit_model(a, T_s)
        self._diagnose(N, T_s)

    def _resolve_N(self, T_s: float) -> int:
        if self.N is not None:
            return int(self.N)
        if self.settling_time is None:
            raise FuelidError(
                "step-ls needs the number of step-response coefficients: pass N or the prior "
                "model's 98 % settling time (settling_time)"
            )
        if not (math.isfinite(self.settling_time) and self.settling_time > 0.0):
            raise FuelidError(f"settling time must be positive, got {self.settling_time}")
        return max(math.ceil(self.settling_time / T_s - 1e-9), 2)

    def _validate(self, N: int, T_s: float) -> None:
        if N < 2:
            raise FuelidError(f"N must be at least 2 (a_1 … a_N), got {N}")
        for name in ("T_f", "delay"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise FuelidError(f"{name} must be finite and non-negative, got {value}")
        if not self.max_condition > 1.0:
            raise FuelidError(f"max_condition must exceed 1, got {self.max_condition}")
        if np.count_nonzero(T_s * np.arange(1, N + 1) > self.delay) < 2:
            raise FuelidError(
                f"delay {self.delay:g} s leaves fewer than two of the N={N} coefficients "
                f"(t = {T_s:g} … {N * T_s:g} s) after the dead time: increase N"
            )

    def _check_excitation(self, phi: FloatArray, N: int, n_changes: int, sv: FloatArray) -> None:
        """Refuse too few rows, a rank below N, or a condition beyond ``max_condition``.

        ``sv`` are Φ's singular values (the fit's SVD, computed once).
        """
        rows = phi.shape[0]
        changes = f"{n_changes} input change{'' if n_changes == 1 else 's'}"
        if rows < N:
            raise NotExcitingError(
                f"only {rows} regression rows carry input information ({changes}): at least "
                f"N={N} needed"
            )
        rank = int(np.count_nonzero(sv > sv[0] * max(phi.shape) * np.finfo(float).eps))
        if rank < N:
            dead = np.flatnonzero(~np.any(phi != 0.0, axis=0)) + 1
            which = (
                f": a_{', a_'.join(str(i) for i in dead)} not excited (a_i needs an input change "
                "i samples before a row k ≥ N)"
                if dead.size
                else ""
            )
            raise NotExcitingError(f"regressor matrix rank {rank} < N={N} ({changes}){which}")
        cond = float(sv[0] / sv[-1])
        if cond > self.max_condition:
            raise NotExcitingError(
                f"regressor condition number {cond:.3g} exceeds {self.max_condition:.3g}: the "
                f"input changes do not separate the N={N} coefficients"
            )

    def _fit_model(self, a: FloatArray, T_s: float) -> None:
        """Stage 2 (:func:`~fuelid.identify._step_shape_fit.fit_step_shape`) and its warnings."""
        N = a.size
        T_f = float(self.T_f)
        shape = fit_step_shape(a, T_s, T_f, self.delay)
        self.newton_iterations_ = shape.iterations
        T, K = shape.T, shape.K
        if not shape.converged:
            self.warnings_.append(
                f"Newton iteration for T did not converge in {_MAX_ITER} steps (T = {T:.4g} s)"
            )
        if shape.at_bound:
            self.warnings_.append(
                f"T reached the search bound ({T:.3g} s): the coefficients do not determine T "
                f"(too fast or too slow for T_s = {T_s:g} s and N = {N})"
            )
        # linearised propagation of cov(â) to (K, T): J = [g, K·dg/dT]
        J = np.column_stack((shape.g, K * shape.g1))
        gain = np.linalg.pinv(J)
        cov_kt = gain @ self.cov_a_ @ gain.T
        resid = a - K * shape.g
        self.K_, self.T_ = float(K), float(T)
        self.K_stderr_ = float(np.sqrt(cov_kt[0, 0]))
        self.T_stderr_ = float(np.sqrt(cov_kt[1, 1]))
        self.fit_rms_ = float(np.sqrt(np.mean(resid**2)))
        self.T2_ = 0.0
        self.stderr_ = {
            "K": self.K_stderr_,
            "T": self.T_stderr_,
            "T2": None,
            "delay": None,
            "T_f": None,
        }
        self.fixed_ = ("T2", "delay", "T_f")
        self.model_ = ProcessModel(K=self.K_, T=self.T_, T_f=T_f, delay=float(self.delay))

    def _diagnose(self, N: int, T_s: float) -> None:
        settle = self.model_.settling_time()
        horizon = N * T_s
        if not settle <= horizon:
            self.warnings_.append(
                f"fitted model's 98 % settling time {settle:.3g} s exceeds N·T_s = {horizon:g} s: "
                "the truncated step response biases a_N, K and T; refit with "
                f"N ≥ {math.ceil(settle / T_s)}"
            )
        if N > _MANY_COEFFICIENTS:
            self.warnings_.append(
                f"N={N} coefficients at T_s = {T_s:g} s: the article's method runs at the control "
                "period (N about 5); decimate the record first or use the output-error fit"
            )
        sign = 1.0 if self.a_[-1] >= 0.0 else -1.0
        steps = sign * np.diff(self.a_, prepend=0.0)
        cov = self.cov_a_
        var = np.diag(cov).copy()
        var[1:] += np.diag(cov)[:-1] - 2.0 * np.diag(cov, k=-1)
        with np.errstate(invalid="ignore"):
            falls = np.flatnonzero(steps < -3.0 * np.sqrt(np.maximum(var, 0.0)))
        if falls.size:
            where = ", ".join(f"a_{i + 1}" for i in falls)
            self.warnings_.append(
                f"step-response coefficients fall significantly at {where} (overshoot, an "
                "unmodelled mode or a record not starting at rest): the over-damped model may "
                "not fit"
            )
