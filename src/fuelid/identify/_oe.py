"""Output-error fit of the continuous-time gray-box model on the raw samples.

Model (the family of :mod:`fuelid.model`; docs/explanation/identification.md §3), for a
record ``u, y`` sampled every ``h`` seconds::

    ŷ[k] = b + K · s[k](T, T2, θ) + Σ_i c_i · p_i^k

- ``s`` is the exact ZOH response of e^(−θs)/((T s+1)(T2 s+1)(T_f s+1)) to the input deviation
  ``u − u_ref`` from rest (``u_ref`` = the pre-record input ``u_before`` when known, else u[0]);
- ``b`` is the output at rest at ``u_ref`` (real logs have offsets);
- ``c_i p_i^k`` (p_i = e^(−h/T_i)) is the free response of an unknown initial state: a record that
  does not start at rest is not fitted as if it did (``initial="estimate"``, the default).

Under white measurement noise minimising Σ(y − ŷ)² is maximum likelihood. The linear parameters
(K, b, c_i) are eliminated by least squares for given time constants and delay (variable
projection), so the nonlinear search runs over one to three parameters only: log T, log T2 and
θ. T_f (and θ, when given) are priors and stay fixed. The delay is fractional and exact.

A record with gaps (:mod:`fuelid.identify._segments`) is fitted jointly: one model and one
output offset ``b`` for all segments, the free-run simulation restarted at each segment from
rest at its first command (the input before a segment is taken as held at that command) plus
its own free response ``Σ_i c_ji p_i^(k − k_j)``; the first segment follows ``initial`` and
``u_before``, every later one ``initial``. Each segment needs at least
:data:`~fuelid.identify._segments.MIN_SEGMENT_SAMPLES` samples.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Literal, Self

import numpy as np
from numpy.typing import NDArray

from fuelid.blas import single_threaded_blas
from fuelid.errors import FuelidError, NotExcitingError
from fuelid.identify._base import Initial
from fuelid.identify._covariance import (
    ResidualAR,
    bread,
    residual_ar,
    sandwich_covariance,
)
from fuelid.identify._diagnostics import (
    CorrelationTest,
    residual_whiteness,
    settled_residuals,
    settled_stretches,
)
from fuelid.identify._long_record import (
    LongRecordSearch,
    is_long,
    search_copy,
    whole_record_fit,
)
from fuelid.identify._order import Candidate, OrderChoice, bic, choose_order
from fuelid.identify._process_estimator import ProcessModelEstimator
from fuelid.identify._progress import StageCallback, StepCounter
from fuelid.identify._search import StepCallback, evaluate_structure, search_structure
from fuelid.identify._segments import MIN_SEGMENT_SAMPLES
from fuelid.identify._variable_projection import (
    GRID_SAMPLES,
    Bounds,
    LinearFit,
    Structure,
    continue_fitted,
    cramer_rao_bound,
    jacobian,
)
from fuelid.io.timeseries import IOData
from fuelid.model import MODEL_KEYS, ProcessModel, nrmse_fit
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]
Order = Literal[1, 2, "auto"]
#: a command change whose response K·|Δu| stays within this many residual standard deviations
#: does not start a transient when the settled residuals are tested (a PI's reaction to the
#: noise moves the command at every scan in closed loop)
NOISE_HIDDEN_CHANGE = 3.0
#: fewest settled samples for judging where the residuals' colour comes from
MIN_SETTLED_SAMPLES = 500
#: lags of the whiteness tests [samples] (residual_whiteness's default)
WHITENESS_LAGS = 25


class OutputError(ProcessModelEstimator):
    """Output-error estimator of K·e^(−θs)/((T s+1)(T2 s+1)(T_f s+1)).

    Parameters
    ----------
    order : 1, 2 or "auto"
        Number of process time constants; "auto" fits both and keeps one by the rule of
        :mod:`fuelid.identify._order` (BIC, and the second lag's own evidence).
    delay : float or None
        Dead time θ [s] held fixed (e.g. the flowmeter's); None estimates it.
    T_f : float
        Flowmeter lag [s], a fixed prior (0 for none).
    initial : "estimate" or "rest"
        Estimate the free response of an unknown initial state, or assume the record starts
        at rest (for a record with gaps: every segment, each at its first command).
    u_before : float or None
        The steady input before the record [input unit]: the plant is taken to be at rest at
        ``u_before`` when the record starts (overrides ``initial`` for the first segment;
        segments after a gap follow ``initial``).
    max_delay : float or None
        Upper bound of the delay search [s] (default: a quarter of the record, at most 60 s).
    covariance : "auto", "white" or "hac"
        The parameters' covariance: "white" σ̂²(JᵀJ)⁻¹; "hac" the sandwich with the residuals'
        spectrum (:mod:`fuelid.identify._covariance`), valid when they are coloured; "auto"
        (default) the sandwich whenever the residual whiteness test fails because of the noise:
        when the residuals are white where the output has settled (the colour is the model's
        misfit after command changes, a function of the input that is the same in every noise
        realisation, so the estimate does not scatter by it), the white covariance with the
        residual standard deviation there (``residual_colour_``).
    full_record : bool
        A long record (:mod:`fuelid.identify._long_record`): False fits a copy of spread-out
        stretches, True searches on the copy and polishes on every sample.
    numerics : Numerics
        How the fit computes (:mod:`fuelid.numerics_mode`): the search's tolerances and
        Jacobians, and the path before issue 26. The default is ``fuelid identify``'s; the
        online windows pass :data:`~fuelid.numerics_mode.WINDOW_NUMERICS`.

    Attributes
    ----------
    K_, T_, T2_, delay_, T_f_ : float
        The fitted model's parameters [output unit / input unit, s] (T2_ = 0 for order 1).
    model_ : ProcessModel
        The same as a model.
    offset_ : float
        Output at rest at ``u_ref_`` [output unit].
    u_ref_ : float
        Input the model's rest state refers to: ``u_before``, else the fitting record's u[0].
    param_names_, params_, cov_ : tuple, ndarray, ndarray
        Every estimated parameter (K, the free nonlinear ones, the offset, the initial-state
        amplitudes ``c0…``), their values and covariance (``covariance_`` says which).
    covariance_ : "white" or "hac"
        How ``cov_`` was computed; ``cov_white_`` is σ̂²(JᵀJ)⁻¹ always.
    residual_ar_ : ResidualAR
        The residuals' autoregressive model (order 0: white), the middle of the sandwich.
    residual_colour_ : str or None
        Why the residuals are coloured, judged by ``covariance="auto"`` when the whiteness test
        fails: "model" (white where the output has settled: the misfit after command changes;
        ``cov_`` is then the white covariance with the residual standard deviation there),
        "noise" (coloured there too) or "unknown" (too little settled output to judge); None
        when they are white (by the test or by their autoregressive model) or not judged.
    settled_whiteness_ : CorrelationTest or None
        The whiteness test where the output has settled behind ``residual_colour_``.
    stderr_ : dict
        Standard error of each model parameter K, T, T2, delay, T_f (None for a fixed one).
    fixed_ : tuple of str
        The model parameters held fixed (priors and structural zeros).
    sigma_, sse_ : float
        Residual standard deviation and sum of squares [output unit, output unit²].
    aic_, bic_ : dict
        Akaike and Bayesian information criteria by order fitted.
    order_choice_ : OrderChoice
        The orders compared, the one kept and why, and whether the intervals are conditional
        on the structure (:mod:`fuelid.identify._order`).
    y_hat_ : ndarray
        ``simulate(data, initial="fitted")`` on the fitting record (per segment, concatenated).
    n_segments_ : int
        Contiguous segments of the fitting record (1 without gaps).
    fit_percent_ : float
        NRMSE fit [%] of ``y_hat_``: ``score(data, initial="fitted")`` on the fitting record.
    n_samples_, sample_time_ : int, float
        Size and sample time [s] of the fitting record.
    warnings_ : list of str
        The data's notes, then what the fit noticed.
    long_record_ : dict
        By order, how a long record was fitted (on a copy, or searched there and polished on
        all of it with ``full_record``: :mod:`fuelid.identify._long_record`); empty for a record
        fitted on itself.
    copy_, copy_y_hat_ : IOData and ndarray, or None
        A long record fitted on its copy (``full_record`` false): the copy, and the copy's own
        ŷ (its residuals are what the tests read). None otherwise. ``y_hat_``,
        ``fit_percent_``, ``n_samples_`` and ``n_segments_`` are the whole record's, every
        other fitted value the copy's.
    whole_record_settled_ : CorrelationTest or None
        A copy's residuals coloured only after command changes are judged again where the
        whole record has settled (its power is the copy's forty-fold): that test, which then
        chose the covariance; None otherwise.

    Examples
    --------
    >>> from fuelid.model import MODEL_KEYS, ProcessModel, nrmse_fit, simulate_model
    >>> u = np.repeat([1.0, 2.0, 1.5, 2.5], 250)
    >>> true = ProcessModel(K=3.0, T=2.0, delay=0.3)
    >>> y = 10.0 + simulate_model(true, u, 0.05)
    >>> est = OutputError(order=1).fit(IOData(u=u, y=y, sample_time=0.05))
    >>> round(est.K_, 6), round(est.T_, 6), round(est.delay_, 6)
    (3.0, 2.0, 0.3)
    """

    _SETTINGS = (
        "order",
        "delay",
        "T_f",
        "initial",
        "u_before",
        "max_delay",
        "covariance",
        "full_record",
        "numerics",
    )

    # K_, T_, T2_, delay_, T_f_, offset_, u_ref_, cov_: ProcessModelEstimator's
    param_names_: tuple[str, ...]
    params_: FloatArray
    cov_white_: FloatArray
    covariance_: Literal["white", "hac"]
    residual_ar_: ResidualAR
    residual_colour_: str | None
    settled_whiteness_: CorrelationTest | None
    stderr_: dict[str, float | None]
    fixed_: tuple[str, ...]
    sigma_: float
    sse_: float
    aic_: dict[int, float]
    bic_: dict[int, float]
    order_choice_: OrderChoice
    fit_percent_: float
    y_hat_: FloatArray
    n_segments_: int
    n_samples_: int
    sample_time_: float
    warnings_: list[str]
    long_record_: dict[int, LongRecordSearch]
    whole_record_settled_: CorrelationTest | None
    copy_: IOData | None
    copy_y_hat_: FloatArray | None
    _state: tuple[Structure, FloatArray]

    def __init__(
        self,
        *,
        order: Order = 1,
        delay: float | None = None,
        T_f: float = 0.0,
        initial: Literal["estimate", "rest"] = "estimate",
        u_before: float | None = None,
        max_delay: float | None = None,
        covariance: Literal["auto", "white", "hac"] = "auto",
        full_record: bool = False,
        numerics: Numerics = DEFAULT_NUMERICS,
    ) -> None:
        self.order = order
        self.delay = delay
        self.T_f = T_f
        self.initial = initial
        self.u_before = u_before
        self.max_delay = max_delay
        self.covariance = covariance
        self.full_record = full_record
        self.numerics = numerics

    # ------------------------------------------------------------------ public API
    def fit(
        self,
        data: IOData,
        init: ProcessModel | None = None,
        *,
        progress: StageCallback | None = None,
    ) -> Self:
        """Fit the model to ``data``; ``init`` warm-starts the search (e.g. the last window).

        ``progress``, when it can show steps (:class:`~fuelid.identify._progress.StepDisplay`),
        is told as each structure's search, polish (a long record) and standard errors start.

        Returns
        -------
        OutputError
            ``self``, with the fitted attributes (ending in ``_``) set.

        Raises
        ------
        NotExcitingError
            Too few samples, or an input that never changes.
        FuelidError
            Bad settings.
        """
        with self._fitting(data):
            self._validate(data)
            orders = (1, 2) if self.order == "auto" else (int(self.order),)
            # the searches' last sensitivities by order (for the stored fits' Jacobians)
            vars(self)["_sensitivities"] = {}
            self.aic_ = {}
            self.long_record_ = {}
            self.copy_, self.copy_y_hat_ = None, None
            self.whole_record_settled_ = None
            # one BLAS thread: the fit alternates long thin products with tiny matrix
            # exponentials, and OpenBLAS's thread hand-over makes the tiny ones ~200x slower
            # (measured: 0.49 s vs 0.15 s for one hour of 50 Hz data)
            with single_threaded_blas():
                if is_long(data) and not self.full_record:
                    candidates = self._fit_copy(data, orders, init, progress)
                elif is_long(data) and len(orders) > 1:
                    candidates = self._fit_orders_lazily(
                        data, orders, init, progress, self.numerics
                    )
                else:
                    candidates = self._fit_orders(data, orders, init, progress, self.numerics)
                self.order_choice_.misfit = self.residual_colour_ == "model"
                self.bic_ = {c.order: c.bic for c in candidates}
            vars(self).pop("_sensitivities", None)
        return self

    def _fit_orders(
        self,
        data: IOData,
        orders: tuple[int, ...],
        init: ProcessModel | None,
        progress: StageCallback | None,
        numerics: Numerics,
    ) -> list[Candidate]:
        """Every order searched and stored in turn, then the rule's choice put back.

        Each order's covariance is computed (the order rule needs them); what ``_store`` set
        is kept, so the chosen order's state is put back, not recomputed (its covariance,
        colour test and Jacobian again). ``numerics``: the search's and the stored fit's
        (``self.numerics``, or their statistical form on a long record's copy).
        """
        steps = StepCounter(progress, len(orders) * (3 if is_long(data) else 2))
        n = data.n_samples
        candidates = []
        stored = {}
        for order in orders:
            st = self._structure(order)
            steps.label = f"order {order}: "
            z, ev = self._fit_structure(data, st, init, numerics, steps)
            self.aic_[order] = _aic(ev, z, n)
            steps("standard errors")
            self._store(data, st, z, ev, numerics)
            stored[order] = dict(vars(self))
            criterion = bic(ev.sse, n, ev.beta.size + z.size)
            candidates.append(Candidate.of_fit(self, order, criterion))
            # a day's regressors are 140 MB: not kept while the next order is fitted
            vars(self)["_sensitivities"].pop(order, None)
            del ev
        self.order_choice_ = choose_order(
            candidates, data.sample_time, meter_lag_given=self.T_f > 0.0
        )
        best = self.order_choice_.chosen
        if best != candidates[-1].order:
            choice = self.order_choice_
            vars(self).update(stored[best])
            self.order_choice_ = choice
        return candidates

    def _fit_orders_lazily(
        self,
        data: IOData,
        orders: tuple[int, ...],
        init: ProcessModel | None,
        progress: StageCallback | None,
        numerics: Numerics,
    ) -> list[Candidate]:
        """A long record's orders searched, then stored only as far as the order rule needs.

        The rule reads of a structure its BIC (from the whole record's residuals, there after
        the polish), and a covariance only of the two-lag fit when BIC prefers it and of the
        order kept (:meth:`~fuelid.identify._order.Candidate.without_covariance`). So the order
        BIC prefers is stored first; when the rule keeps the other, that one is stored too (and
        is the one left in place). The others' standard errors are not computed
        (``stderr_computed`` false in the JSON ``structure.compared``): on a day at 50 Hz each
        costs over a second, and no number printed for the kept model depends on them.
        """
        steps = StepCounter(progress, 2 * len(orders) + 1)
        n = data.n_samples
        found: dict[int, tuple[Structure, FloatArray, FloatArray]] = {}
        candidates: dict[int, Candidate] = {}
        last: LinearFit | None = None
        for order in orders:
            st = self._structure(order)
            steps.label = f"order {order}: "
            z, last = self._fit_structure(data, st, init, numerics, steps)
            self.aic_[order] = _aic(last, z, n)
            criterion = bic(last.sse, n, last.beta.size + z.size)
            found[order] = (st, z, last.beta.copy())
            T, T2, delay = st.unpack(z)
            model = ProcessModel(K=float(last.beta[0]), T=T, T2=T2, T_f=st.T_f, delay=delay)
            candidates[order] = Candidate.without_covariance(
                order, criterion, model, ("K", *st.nonlinear_names), last.beta.size + z.size
            )
            if order != orders[-1]:  # a day's regressors are 140 MB: only the last one kept
                vars(self)["_sensitivities"].pop(order, None)
                last = None
        need = min(candidates.values(), key=lambda c: c.bic).order  # BIC's preference
        while True:
            st, z, _ = found[need]
            steps.label = f"order {need}: "
            steps("standard errors")
            if last is None or need != orders[-1]:
                # the other order's regressors go before these are formed
                last = None
                vars(self)["_sensitivities"].pop(orders[-1], None)
                last = evaluate_structure(data, st, z, numerics)
            self._store(data, st, z, last, numerics)
            last = None
            candidates[need] = Candidate.of_fit(self, need, candidates[need].bic)
            self.order_choice_ = choose_order(
                list(candidates.values()), data.sample_time, meter_lag_given=self.T_f > 0.0
            )
            if candidates[self.order_choice_.chosen].stderr_computed:
                return list(candidates.values())
            need = self.order_choice_.chosen
            steps.extend(1)

    def _fit_copy(
        self,
        data: IOData,
        orders: tuple[int, ...],
        init: ProcessModel | None,
        progress: StageCallback | None,
    ) -> list[Candidate]:
        """A long record fitted on its copy; the fitted state and the fit % on all of it.

        The copy (:func:`~fuelid.identify._long_record.search_copy`) is fitted as any record of
        its size: the estimates, their covariance, the order choice and the residual tests are
        its own (:mod:`fuelid.identify._long_record` says why they are right for the estimates
        reported). Then the kept model's offset and each segment's initial state are fitted on
        the whole record, K and the dynamics held
        (:func:`~fuelid.identify._long_record.whole_record_fit`): ``simulate(data, "fitted")``
        and ``fit_percent_`` are the whole record's.
        """
        copy = search_copy(data)
        vars(self).update(_on_copy=True, _whole_record=data, _whole_fits={})
        try:
            # the online windows' numerics (Levenberg–Marquardt with analytic sensitivities,
            # stopping within a few hundredths of a standard error): twice as fast as the
            # reference search on the copy, and what they leave moves no estimate by more than
            # a small fraction of the copy's standard error
            statistical = self.numerics.statistical()
            candidates = self._fit_orders(copy, orders, init, progress, statistical)
            whole_fits = vars(self)["_whole_fits"]
        finally:
            for name in ("_on_copy", "_whole_record", "_whole_fits"):
                vars(self).pop(name, None)
        self.copy_, self.copy_y_hat_ = copy, self.y_hat_
        st, _ = self._state
        known = whole_fits.get(st.order)
        if known is not None and known[1][0] == self.K_:
            st, beta, self.y_hat_ = known  # the colour judgement's, at this very model
        else:
            # the whole record's own segments: after a real gap, its initial condition setting
            st = replace(st, later=self.initial)
            beta, self.y_hat_ = whole_record_fit(
                st, self.K_, self.T_, self.T2_, self.delay_, data, self.u_ref_, self.numerics
            )
        del whole_fits
        self._state = (st, beta)
        self.n_samples_, self.n_segments_ = data.n_samples, data.n_segments
        self.fit_percent_ = nrmse_fit(data.y, self.y_hat_)
        # the record's own notes (gaps, fills), which the copy does not carry
        self.warnings_ = [*data.notes, *(w for w in self.warnings_ if w not in copy.notes)]
        done = LongRecordSearch(data.n_samples, copy.n_samples, copy.n_segments, 0, True, "copy")
        self.long_record_ = dict.fromkeys(orders, done)
        return candidates

    def _whole_record_colour(self, st: Structure) -> tuple[str, float | None]:
        """A copy's "model" colour judged again on the whole record's settled residuals.

        The copy's settled samples (a fortieth of a day's) can be too few to see a mild colour
        of the noise that the whole record's show: on the day of the benchmark p = 0.87 on the
        copy, 0.0015 on the whole record, and σ²(JᵀJ)⁻¹ at the settled level then gave the
        copy standard errors 1.5-11 times too small (the sandwich's match √(N/n) times the
        whole record's within 5 %). The whole record's residuals at the copy's model (the
        offset and initial states fitted, :func:`~fuelid.identify._long_record.whole_record_fit`)
        cost one pass; kept by order for the fitted state when that order is kept.
        """
        whole: IOData = vars(self)["_whole_record"]
        st = replace(st, later=self.initial)
        beta, y_hat = whole_record_fit(
            st, self.K_, self.T_, self.T2_, self.delay_, whole, self.u_ref_, self.numerics
        )
        vars(self)["_whole_fits"][st.order] = (st, beta, y_hat)
        judged = self._colour_source(whole, whole.y - y_hat)
        self.whole_record_settled_ = self.settled_whiteness_
        return judged

    def predict(self, data: IOData, horizon: int = 1, initial: Initial = "rest") -> FloatArray:
        """k-step-ahead prediction ŷ(t | t − k) of the output, k = ``horizon`` [output unit].

        The output-error model has the noise model H = 1 (white noise added to the output), so
        its k-step-ahead predictor W_k·G·u + (1 − W_k)·y, W_k = H̄_k·H⁻¹, reduces to G·u for
        every k ≥ 1: the prediction does not use past outputs and equals the free-run
        simulation (Ljung, *System Identification*, 2nd ed., 1999, §3.2). So this returns
        ``simulate(data, initial)``; ``horizon`` is checked and otherwise has no effect.
        ``initial`` defaults to ``"rest"`` (the record starts at rest at its first input).
        """
        self._check_horizon(horizon)
        return self.simulate(data, initial)

    def _fitted_regression(self) -> tuple[Structure, FloatArray]:
        return self._state

    # ------------------------------------------------------------------ internals
    def _structure(self, order: int) -> Structure:
        initial = "rest" if self.u_before is not None else self.initial
        # a copy's later segments are stretches cut from a running record, never at rest
        later = "estimate" if vars(self).get("_on_copy") else self.initial
        return Structure(order, self.T_f, self.delay, initial, self.u_before, later)

    def _colour_source(self, data: IOData, residual: FloatArray) -> tuple[str, float | None]:
        """Whether coloured residuals are white where settled, and the noise's level there.

        Settled: two of the model's settling times after the last command change whose
        response K·|Δu| the noise does not hide (over :data:`NOISE_HIDDEN_CHANGE` residual
        standard deviations) or gap; each stretch with its line removed
        (:func:`~fuelid.identify._diagnostics.settled_residuals`), so a steady-state error that
        drifts with the fuel temperature is not taken for colour.

        Returns
        -------
        (str, float or None)
            "model" (white there: the colour is the misfit after command changes) with the
            residual standard deviation there (the noise's, without the misfit's power),
            "noise" (coloured there too) or "unknown" (under :data:`MIN_SETTLED_SAMPLES`
            settled samples), with None.
        """
        try:
            settle = self.model_.settling_time(numerics=self.numerics)
        except (FuelidError, ValueError, ArithmeticError):
            return "unknown", None
        gain = abs(self.K_)
        stretches = settled_stretches(
            data.u,
            data.sample_time,
            settle,
            data.segment_starts,
            min_length=2 * WHITENESS_LAGS + 1,
            min_change=NOISE_HIDDEN_CHANGE * self.sigma_ / gain if gain > 0.0 else 0.0,
        )
        parts, starts, removed = settled_residuals(residual, stretches, detrend=True)
        if parts.size < MIN_SETTLED_SAMPLES:
            return "unknown", None
        test = residual_whiteness(parts, WHITENESS_LAGS, starts, numerics=self.numerics)
        self.settled_whiteness_ = test
        if not test.passed:
            return "noise", None
        return "model", math.sqrt(float(parts @ parts) / max(parts.size - removed, 1))

    def _validate(self, data: IOData) -> None:
        if self.order not in (1, 2, "auto"):
            raise FuelidError(f"order must be 1, 2 or 'auto', got {self.order!r}")
        if self.initial not in ("estimate", "rest"):
            raise FuelidError(f"initial must be 'estimate' or 'rest', got {self.initial!r}")
        if self.covariance not in ("auto", "white", "hac"):
            raise FuelidError(
                f"covariance must be 'auto', 'white' or 'hac', got {self.covariance!r}"
            )
        for name in ("T_f", "delay"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= 0.0):
                raise FuelidError(f"{name} must be finite and non-negative, got {value}")
        if self.max_delay is not None and not (
            math.isfinite(self.max_delay) and self.max_delay > 0.0
        ):
            raise FuelidError(f"max_delay must be positive, got {self.max_delay}")
        if self.u_before is not None and not math.isfinite(self.u_before):
            raise FuelidError(f"u_before must be finite, got {self.u_before}")
        if data.n_samples < 20:
            raise NotExcitingError(f"{data.n_samples} samples are too few to fit the model")
        short = [
            f"{j + 1} ({b - a} samples)"
            for j, (a, b) in enumerate(data.segment_bounds())
            if b - a < MIN_SEGMENT_SAMPLES
        ]
        if data.n_segments > 1 and short:
            raise FuelidError(
                f"segment {', '.join(short)} of the {data.n_segments} segments of this record "
                f"has fewer than {MIN_SEGMENT_SAMPLES} samples, too few to estimate its own "
                "initial state: leave it out (fuelid.identify._segments.drop_short_segments)"
            )
        if np.ptp(data.u) == 0.0 and (self.u_before is None or self.u_before == data.u[0]):
            raise NotExcitingError("the input never changes: nothing to identify")

    def _delay_bound(self, data: IOData) -> float:
        record = data.n_samples * data.sample_time
        return self.max_delay if self.max_delay is not None else min(0.25 * record, 60.0)

    def _fit_structure(
        self,
        data: IOData,
        st: Structure,
        init: ProcessModel | None,
        numerics: Numerics,
        step: StepCallback | None = None,
    ) -> tuple[FloatArray, LinearFit]:
        if step is not None and not is_long(data):
            step("search")
        found = search_structure(data, st, init, self._delay_bound(data), step, numerics=numerics)
        if found.sensitivities is not None:  # the search's last, for the stored fit's Jacobian
            vars(self).setdefault("_sensitivities", {})[st.order] = found.sensitivities
        if found.long_record is not None:
            vars(self).setdefault("long_record_", {})[st.order] = found.long_record
        return found.z, found.fit

    def _store(
        self, data: IOData, st: Structure, z: FloatArray, ev: LinearFit, numerics: Numerics
    ) -> None:
        T, T2, delay = st.unpack(z)
        h = data.sample_time
        u_ref = st.u_before if st.u_before is not None else float(data.u[0])
        n = data.n_samples
        self.K_, self.T_, self.T2_, self.delay_, self.T_f_ = (
            float(ev.beta[0]),
            T,
            T2,
            delay,
            st.T_f,
        )
        self.offset_ = float(ev.beta[1])
        self._state = (st, ev.beta.copy())
        self.n_segments_ = data.n_segments
        self.u_ref_ = u_ref
        self.y_hat_ = data.y - ev.residual
        self.sse_ = ev.sse
        self.n_samples_ = n
        self.sample_time_ = h
        self.fit_percent_ = nrmse_fit(data.y, self.y_hat_)
        # covariance of all free parameters from the Jacobian of ŷ at the optimum
        nl_names = st.nonlinear_names
        values = {"T": T, "T2": T2, "delay": delay}
        bounds = data.segment_bounds()
        known = vars(self).get("_sensitivities", {}).get(st.order)
        # the search's sensitivities at this very fit (its last Jacobian), not computed again
        sens = known[1] if known is not None and known[0] is ev else None
        names, J = jacobian(
            st, values, ev.beta, data.u, h, u_ref, ev.Phi, bounds, sens, numerics=numerics
        )
        # spent: J holds their columns now (a day's regressors and sensitivities are 140 and
        # 100 MB, not to be kept beside J's 240 through the covariances)
        vars(self).get("_sensitivities", {}).pop(st.order, None)
        ev.Phi = ev.Phi[:0]
        del known, sens
        dof = max(n - len(names), 1)
        self.sigma_ = math.sqrt(ev.sse / dof)
        self.param_names_ = names
        self.params_ = np.array([self.K_, *(values[nm] for nm in nl_names), *ev.beta[1:]])
        # white residuals: σ²(JᵀJ)⁻¹; coloured noise (the whiteness test fails, and where the
        # output has settled too): the sandwich with the residuals' own spectrum, which
        # σ²(JᵀJ)⁻¹ understates several times. Residuals coloured only after command changes
        # are the model's misfit (a nonlinear plant, a lag the structure lacks): the same in
        # every noise realisation, so the estimate does not scatter by it, and the sandwich
        # would count its slow colour as noise (2-40 times too wide, median 7, on the soak)
        # one SVD of J for every covariance below (white, sandwich, white at the settled level)
        inverse = bread(J, numerics)
        self.cov_white_, singular = self.sigma_**2 * inverse[0], inverse[1]
        self.residual_ar_ = residual_ar(ev.residual, bounds, numerics=numerics)
        coloured = not residual_whiteness(
            ev.residual, segment_starts=data.segment_starts, numerics=numerics
        ).passed
        self.residual_colour_, self.settled_whiteness_ = None, None
        self.whole_record_settled_ = None
        noise_sigma: float | None = None
        if coloured and self.covariance == "auto" and self.residual_ar_.order > 0:
            self.residual_colour_, noise_sigma = self._colour_source(data, ev.residual)
            if self.residual_colour_ == "model" and "_whole_record" in vars(self):
                self.residual_colour_, noise_sigma = self._whole_record_colour(st)
        use_sandwich = self.covariance == "hac" or (
            self.covariance == "auto" and coloured and self.residual_colour_ != "model"
        )
        if use_sandwich and self.residual_ar_.order > 0:
            # J is not needed after: filtered in place (a day's J is 240 MB)
            self.cov_, singular = sandwich_covariance(
                J, self.residual_ar_, bounds, inverse, overwrite=True, numerics=numerics
            )
            self.covariance_ = "hac"
        elif noise_sigma is not None:
            # white noise of the level it has where the output settled: σ̂ over all residuals
            # counts the misfit's power as noise too
            self.cov_, singular = noise_sigma**2 * inverse[0], inverse[1]
            self.covariance_ = "white"
        else:
            self.cov_, self.covariance_ = self.cov_white_, "white"
        unidentified = [names[i] for i in singular]
        variance = np.diag(self.cov_)
        # a negative variance (rounding, an undetermined pair) is no standard error: None below
        sd = np.sqrt(np.where(variance >= 0.0, variance, np.nan))
        self.stderr_ = {"K": None, "T": None, "T2": None, "delay": None, "T_f": None}
        for name, s in zip(names, sd, strict=False):
            if name in self.stderr_ and math.isfinite(s):
                self.stderr_[name] = float(s)
        # priors and structural zeros are held fixed: T_f always, the delay when given, T2 = 0
        # in a first-order model
        self.fixed_ = tuple(name for name in ("T2", "delay", "T_f") if name not in nl_names)
        self.warnings_ = list(data.notes)
        shown = [name for name in unidentified if name in MODEL_KEYS]
        if shown:
            self.warnings_.append(
                f"{', '.join(shown)} cannot be told apart from the other parameters with this "
                "log (their information is singular, e.g. two equal lags): no standard error "
                "or interval for them; a log with more or larger steps, or a prior, fixes it"
            )


def _aic(fit: LinearFit, z: FloatArray, n: int) -> float:
    """Akaike's criterion N·ln(SSE/N) + 2k of a fit with ``z`` searched and β linear."""
    return n * math.log(max(fit.sse, 1e-300) / n) + 2 * (fit.beta.size + z.size)


__all__ = ["GRID_SAMPLES", "Bounds", "OutputError", "continue_fitted", "cramer_rao_bound"]
