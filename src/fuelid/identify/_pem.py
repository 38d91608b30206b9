r"""Prediction-error fit with a noise model: the Box–Jenkins structure.

Model, for a record ``u, y`` sampled every ``h`` seconds (the process part is that of
:mod:`fuelid.identify._oe`, with the same settings, priors and initial states)::

    y[k] = ŷ_p[k] + v[k],      ŷ_p[k] = b + K·s[k](T, T2, θ) + Σ_i c_i·p_i^k
    v[k] = C(q)/D(q)·e[k],     e white with variance σ_e²
    C(q) = 1 + c_1 q⁻¹ + … + c_nc q⁻ⁿᶜ,   D(q) = 1 + d_1 q⁻¹ + … + d_nd q⁻ⁿᵈ

(``q⁻¹`` the backward shift; nc, nd ∈ 0…2). The prediction errors are

.. math:: \varepsilon[k] = \frac{D(q)}{C(q)}\,(y[k] - \hat y_p[k])

and the fit minimises Σ ε² over the process and the noise parameters jointly (Ljung, *System
Identification*, 2nd ed., 1999, §7.2–7.3). With e Gaussian this is maximum likelihood, so the
estimate is efficient under coloured noise (its covariance reaches the Box–Jenkins Cramér–Rao
bound), where the output-error fit (C = D = 1) is only consistent; and on closed-loop data (the
input correlated with the noise through a controller) the direct method is consistent when the
noise model is in the family, where the output-error fit is biased (Ljung §13.4).

How it is computed
------------------
- **Noise parametrisation.** C and D are built from reflection coefficients κ = tanh(η)
  (Levinson step-up), so every η gives a stable D and a minimum-phase C: the predictor
  D/C stays stable during the search, with no clipping. The search runs over η.
- **Variable projection.** For given (T, T2, θ) and η, the linear parameters (K, offset,
  initial-state amplitudes) are the least-squares solution of D/C·y on D/C·Φ (the output-error
  regressors filtered by the noise model), so the nonlinear search runs over at most three
  process parameters and four noise parameters.
- **Segments.** The noise filter restarts at every segment from zero initial conditions (the
  noise before a gap is unknown and nothing is filtered across one); the first ``nd`` prediction
  errors of each segment (which would need outputs before the segment) are left out of the
  criterion: the conditional likelihood given those outputs, exact for an autoregressive noise
  model.
- **Noise order** ("auto"). Every candidate (nc, nd) of :data:`NOISE_ORDERS` is fitted to the
  output-error residual by the Hannan–Rissanen method (a long autoregression estimates the
  innovations, then one linear regression per candidate: a handful of filter passes in all),
  and the one with the lowest Bayesian information criterion BIC = N·ln(Σε²/N) + k·ln N wins;
  the joint fit then refines that order only. BIC rather than AIC: the records are long
  (N = 10⁴–10⁶), and AIC's penalty of 2 per parameter picks a spurious noise term in about one
  white-noise record in six, while BIC's ln N ≈ 10 keeps the output-error model
  (nc = nd = 0) when the noise is white and still finds any coloured noise worth more than a
  few samples' worth of Σε². ``noise_criterion="aic"`` is available. Every candidate's
  criterion is summed over the same samples (the first two of each segment left out).
- **Process order** ("auto"): both orders are fitted, each with its own noise model, and one is
  kept by the rule of :mod:`fuelid.identify._order` on the prediction errors' BIC and the second
  lag's own evidence, as :class:`OutputError` does.
- **Free run.** ``simulate``, ``y_hat_`` and ``fit_percent_`` use K and the dynamics of the
  fit with the output level (offset, initial states) fitted by least squares to the
  unfiltered record: under a drifting noise model (a pole of D near 1) the prediction errors
  hardly constrain the level, and the free run must not inherit an arbitrary one.
- **Covariance.** The asymptotic covariance of the prediction-error estimate,
  σ̂_e²·(ΨᵀΨ)⁻¹ with Ψ = ∂ε/∂p over every estimated parameter (process, offset, initial
  states, noise coefficients), through the SVD of the column-scaled Ψ (directions the data do
  not determine get no standard error). The process columns are the output-error Jacobian
  filtered by −D/C; the noise columns are exact: ∂ε/∂d_i = q⁻ⁱ·(y − ŷ_p)/C and
  ∂ε/∂c_i = −q⁻ⁱ·ε/C. At the true parameters this is the Box–Jenkins Cramér–Rao bound.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal, Self

import numpy as np
from numpy.typing import NDArray

from fuelid.blas import single_threaded_blas
from fuelid.errors import FuelidError
from fuelid.identify._base import Initial
from fuelid.identify._covariance import white_covariance
from fuelid.identify._noise import (
    MAX_NOISE_DEGREE,
    NOISE_ORDERS,
    SELECTION_WARMUP,
    NoiseOrder,
    NoiseShape,
    check_noise_start,
    filter_segments,
    hannan_rissanen,
    information_criterion,
    noise_coefficients,
    used_samples,
)
from fuelid.identify._oe import OutputError
from fuelid.identify._order import Candidate, OrderChoice, bic, choose_order
from fuelid.identify._prediction_errors import (
    JointFit,
    joint_fit,
    noise_model_summary,
    noise_model_warnings,
    predicted_noise,
    prediction_error_jacobian,
)
from fuelid.identify._process_estimator import ProcessModelEstimator
from fuelid.identify._variable_projection import (
    Structure,
    jacobian,
    solve_linear,
    start_from_model,
)
from fuelid.io.timeseries import IOData
from fuelid.model import MODEL_KEYS, ProcessModel, nrmse_fit
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]
Bounds = list[tuple[int, int]]
Order = Literal[1, 2, "auto"]


class PredictionError(ProcessModelEstimator):
    """Prediction-error (Box–Jenkins) estimator of K·e^(−θs)/((T s+1)(T2 s+1)(T_f s+1)).

    The process part and its settings are those of :class:`~fuelid.identify._oe.OutputError`;
    the output noise is v = C(q)/D(q)·e with e white (module docstring for the equations).

    Parameters
    ----------
    order : 1, 2 or "auto"
        Number of process time constants; "auto" fits both (each with its noise model) and
        keeps one by the rule of :mod:`fuelid.identify._order` (the prediction errors' BIC and
        the second lag's own evidence).
    delay : float or None
        Dead time θ [s] held fixed (e.g. the flowmeter's); None estimates it.
    T_f : float
        Flowmeter lag [s], a fixed prior (0 for none).
    initial : "estimate" or "rest"
        Estimate each segment's initial state, or assume the record starts at rest.
    u_before : float or None
        The steady input before the record [input unit] (as for OutputError).
    max_delay : float or None
        Upper bound of the delay search [s] (default: a quarter of the record, at most 60 s).
    noise_order : "auto" or (nc, nd)
        Degrees of C and D (each 0…2); "auto" chooses among :data:`NOISE_ORDERS` by
        ``noise_criterion``; (0, 0) is the output-error fit.
    noise_criterion : "bic" or "aic"
        Information criterion of the noise-order choice (BIC by default: module docstring).
    numerics : Numerics
        How the fit computes (:mod:`fuelid.numerics_mode`), as for OutputError; the joint
        search is scipy's ``trf`` at its tolerances whatever its Jacobians.

    Attributes
    ----------
    K_, T_, T2_, delay_, T_f_, u_ref_ : float
        As for OutputError [output unit / input unit, s, input unit].
    offset_ : float
        Output at rest at ``u_ref_`` of the free-run simulation [output unit]: with K and the
        dynamics fitted, the offset and initial states are the least-squares level of the
        simulation on the unfiltered record (``params_`` holds the prediction-error estimate,
        nearly free when the noise drifts).
    model_ : ProcessModel
        The process model.
    noise_model_ : dict
        ``C`` and ``D`` (coefficients in powers of q⁻¹, leading 1), ``nc``, ``nd``,
        ``poles`` and ``zeros`` (roots of D and C in z), ``sigma_e`` (innovation standard
        deviation [output unit]), ``sigma_v`` (stationary standard deviation of the noise
        C/D·e [output unit]), ``criterion`` (its value per order tried, keyed ``"nc=…,nd=…"``;
        empty when the order was given or warm-started) and ``criterion_name``.
    param_names_, params_, cov_ : tuple, ndarray, ndarray
        Every estimated parameter (K, the free nonlinear ones, the offset, the initial-state
        amplitudes ``c0…``, the noise coefficients ``noise_d1…``, ``noise_c1…``), their values
        and asymptotic covariance σ̂_e²·(ΨᵀΨ)⁻¹, Ψ = ∂ε/∂p.
    covariance_method_ : str
        ``"noise-model"``: the covariance the standard errors come from.
    stderr_ : dict
        Standard error of K, T, T2, delay, T_f (None for a fixed one).
    fixed_ : tuple of str
        Model parameters held fixed.
    sigma_, sse_ : float
        Innovation standard deviation σ̂_e and Σε² over the samples in the criterion.
    aic_, bic_ : dict
        Akaike and Bayesian criteria of the prediction errors by process order fitted.
    order_choice_ : OrderChoice
        The orders compared, the one kept and why (:mod:`fuelid.identify._order`).
    residuals_ : ndarray
        The prediction errors ε = D/C·(y − ``y_hat_``) of the one-step predictor, one per
        sample, the filter restarted from zero at each segment (its first ``nd`` samples are
        outside the criterion); ``y − residuals_`` is ``predict(data, 1, "fitted")``.
    y_hat_ : ndarray
        Free-run simulation on the fitting record (``simulate(data, "fitted")``).
    fit_percent_ : float
        NRMSE fit [%] of the free-run simulation ``y_hat_`` (comparable with OutputError's).
    one_step_fit_percent_ : float
        NRMSE fit [%] of the one-step-ahead prediction y − ε (near 100 % for any good noise
        model: not a measure of the process model).
    n_segments_, n_samples_, sample_time_ : int, int, float
        Segments, size and sample time [s] of the fitting record.
    warnings_ : list of str
        The data's notes, then what the fit noticed.

    Examples
    --------
    >>> import scipy.signal
    >>> from fuelid.model import simulate_model
    >>> rng = np.random.default_rng(1)
    >>> u = np.repeat([1.0, 2.0, 1.5, 2.5, 1.0, 2.0], 500)
    >>> e = rng.normal(0.0, 0.01, u.size)
    >>> v = scipy.signal.lfilter([1.0], [1.0, -0.9], e)  # AR(1) noise, pole 0.9
    >>> y = 10.0 + simulate_model(ProcessModel(K=3.0, T=2.0, delay=0.3), u, 0.05) + v
    >>> est = PredictionError(order=1, delay=0.3).fit(IOData(u=u, y=y, sample_time=0.05))
    >>> est.noise_model_["nc"], est.noise_model_["nd"], round(est.noise_model_["poles"][0], 1)
    (0, 1, 0.9)
    >>> abs(est.K_ - 3.0) < 3 * est.stderr_["K"], abs(est.T_ - 2.0) < 3 * est.stderr_["T"]
    (True, True)
    """

    _SETTINGS = (
        "order",
        "delay",
        "T_f",
        "initial",
        "u_before",
        "max_delay",
        "noise_order",
        "noise_criterion",
        "numerics",
    )

    # K_, T_, T2_, delay_, T_f_, offset_, u_ref_, cov_: ProcessModelEstimator's
    param_names_: tuple[str, ...]
    params_: FloatArray
    covariance_method_: str
    stderr_: dict[str, float | None]
    fixed_: tuple[str, ...]
    sigma_: float
    sse_: float
    aic_: dict[int, float]
    bic_: dict[int, float]
    order_choice_: OrderChoice
    noise_model_: dict[str, Any]
    residuals_: FloatArray
    y_hat_: FloatArray
    fit_percent_: float
    one_step_fit_percent_: float
    n_segments_: int
    n_samples_: int
    sample_time_: float
    warnings_: list[str]
    _state: tuple[Structure, FloatArray, FloatArray, FloatArray]

    def __init__(
        self,
        *,
        order: Order = 1,
        delay: float | None = None,
        T_f: float = 0.0,
        initial: Literal["estimate", "rest"] = "estimate",
        u_before: float | None = None,
        max_delay: float | None = None,
        noise_order: Literal["auto"] | NoiseOrder = "auto",
        noise_criterion: Literal["bic", "aic"] = "bic",
        numerics: Numerics = DEFAULT_NUMERICS,
    ) -> None:
        self.order = order
        self.delay = delay
        self.T_f = T_f
        self.initial = initial
        self.u_before = u_before
        self.max_delay = max_delay
        self.noise_order = noise_order
        self.noise_criterion = noise_criterion
        self.numerics = numerics

    # ------------------------------------------------------------------ public API
    def fit(
        self,
        data: IOData,
        init: ProcessModel | PredictionError | None = None,
        noise_init: Mapping[str, Any] | None = None,
    ) -> Self:
        """Fit the process and noise models to ``data``.

        Parameters
        ----------
        data : IOData
            The record (with gaps: one model, a noise filter and an initial state per segment).
        init : ProcessModel or fitted PredictionError, optional
            Warm start (the last window's fit). A model skips the output-error grid search and,
            with ``order="auto"``, the process-order choice (its own order is kept: 2 when it
            has a T2). A fitted PredictionError (this one included) also gives the noise model.
        noise_init : mapping, optional
            A noise model to start from (``C`` and ``D`` coefficient lists, e.g. a previous
            ``noise_model_``): its order is kept and the noise-order search is skipped. With
            both, the fit starts at once from the previous optimum: one joint search, nothing
            else (the window refit of the online service).

        Returns
        -------
        PredictionError
            ``self``, fitted.

        Raises
        ------
        NotExcitingError
            Too few samples, or an input that never changes.
        FuelidError
            Bad settings.
        """
        # read the warm start before _fitting forgets this estimator's own previous fit
        process, noise = self._warm_start(init, noise_init)
        with self._fitting(data):
            self._validate(data)
            if process is not None and self.order == "auto":
                orders: tuple[int, ...] = (2 if process.T2 > 0.0 else 1,)
            else:
                orders = (1, 2) if self.order == "auto" else (int(self.order),)
            with single_threaded_blas():  # see OutputError.fit: tiny matrices, long products
                fits = {order: self._fit_order(data, order, process, noise) for order in orders}
                self.aic_ = {
                    order: information_criterion(
                        f.sse, int(f.used.sum()), f.x.size + f.beta.size, "aic"
                    )
                    for order, f in fits.items()
                }
                # each order stored in turn for its covariance, which the order rule needs
                candidates = []
                for order, f in fits.items():
                    self._store(data, f)
                    k = f.x.size + f.beta.size
                    candidates.append(
                        Candidate.of_fit(self, order, bic(f.sse, int(f.used.sum()), k))
                    )
                self.order_choice_ = choose_order(
                    candidates, data.sample_time, meter_lag_given=self.T_f > 0.0
                )
                best = self.order_choice_.chosen
                if best != candidates[-1].order:
                    self._store(data, fits[best])
                self.bic_ = {c.order: c.bic for c in candidates}
        return self

    def predict(self, data: IOData, horizon: int = 1, initial: Initial = "rest") -> FloatArray:
        r"""k-step-ahead prediction ŷ(t | t − k), k = ``horizon`` [output unit].

        With the noise model H = C/D the predictor is (Ljung 1999, eq. 3.31)

        .. math:: \hat y(t|t-k) = \hat y_p(t) + (1 - \bar H_k(q) H^{-1}(q))\,(y(t) - \hat y_p(t))

        where ŷ_p is the free-run process output (:meth:`simulate` with ``initial``) and
        H̄_k = Σ_{i<k} h_i q⁻ⁱ the first k terms of H's impulse response. For k = 1 this is
        ŷ_p + (1 − D/C)(y − ŷ_p); as k grows the noise becomes unpredictable and the prediction
        tends to the free run, which it equals once k reaches a segment's length. The noise
        filter starts from zero at each segment.
        """
        self._check_horizon(horizon)
        y_p = self.simulate(data, initial)
        _, _, C, D = self._state
        if C.size == 1 and D.size == 1:
            return y_p
        # a horizon beyond the longest segment predicts nothing of the noise: the free run
        k = min(int(horizon), data.n_samples)
        v_hat = predicted_noise(data.y - y_p, C, D, k, data.segment_bounds())
        return np.asarray(y_p + v_hat, dtype=float)

    # ------------------------------------------------------------------ internals
    def _oe(self, order: int) -> OutputError:
        return OutputError(
            order=1 if order == 1 else 2,
            delay=self.delay,
            T_f=self.T_f,
            initial=self.initial,
            u_before=self.u_before,
            max_delay=self.max_delay,
            numerics=self.numerics,
        )

    def _structure(self, order: int) -> Structure:
        initial = "rest" if self.u_before is not None else self.initial
        return Structure(order, self.T_f, self.delay, initial, self.u_before, self.initial)

    @staticmethod
    def _warm_start(
        init: ProcessModel | PredictionError | None, noise_init: Mapping[str, Any] | None
    ) -> tuple[ProcessModel | None, tuple[list[float], list[float]] | None]:
        noise: tuple[list[float], list[float]] | None = None
        model: ProcessModel | None
        if isinstance(init, PredictionError):
            model = init.model_
            noise = (list(init.noise_model_["C"]), list(init.noise_model_["D"]))
        else:
            model = init
        if noise_init is not None:
            noise = noise_coefficients(noise_init)
        if noise is not None:
            check_noise_start(*noise)
        return model, noise

    def _validate(self, data: IOData) -> None:
        order = self.noise_order
        if order != "auto" and not (
            isinstance(order, tuple | list)
            and len(order) == 2
            and all(isinstance(d, int | np.integer) and not isinstance(d, bool) for d in order)
            and all(0 <= int(d) <= MAX_NOISE_DEGREE for d in order)
        ):
            raise FuelidError(
                f"noise_order must be 'auto' or (nc, nd) with degrees 0…{MAX_NOISE_DEGREE}, "
                f"got {order!r}"
            )
        if self.noise_criterion not in ("bic", "aic"):
            raise FuelidError(
                f"noise_criterion must be 'bic' or 'aic', got {self.noise_criterion!r}"
            )
        # the process settings and the record are checked as OutputError checks them
        self._oe(1).set_params(order=self.order)._validate(data)

    def _fit_order(
        self,
        data: IOData,
        order: int,
        process: ProcessModel | None,
        noise_start: tuple[list[float], list[float]] | None,
    ) -> JointFit:
        st = self._structure(order)
        bounds = data.segment_bounds()
        n = data.n_samples
        criterion: dict[str, float] = {}
        if process is not None and noise_start is not None:
            # window refit: straight to the joint search from the previous optimum
            noise = NoiseShape(len(noise_start[0]) - 1, len(noise_start[1]) - 1)
            if self.noise_order != "auto":
                noise = NoiseShape(int(self.noise_order[0]), int(self.noise_order[1]))
            z0 = start_from_model(process, st)
            eta0 = noise.eta(*noise_start)
        else:
            # the output-error fit (its search only: no covariance, no diagnostics)
            z0, ev = self._oe(order)._fit_structure(data, st, process, self.numerics)
            r = ev.residual
            if self.noise_order == "auto":
                candidates: tuple[NoiseOrder, ...] = NOISE_ORDERS
            else:
                candidates = ((int(self.noise_order[0]), int(self.noise_order[1])),)
            if noise_start is not None and self.noise_order == "auto":
                candidates = ((len(noise_start[0]) - 1, len(noise_start[1]) - 1),)
            etas = hannan_rissanen(r, candidates, bounds)
            if len(candidates) > 1:
                keep = used_samples(bounds, n, SELECTION_WARMUP)
                n_used = int(keep.sum())
                k_process = z0.size + ev.beta.size  # nonlinear, K, offset, amplitudes
                for (nc, nd), (_, sse) in etas.items():
                    criterion[f"nc={nc},nd={nd}"] = information_criterion(
                        sse, n_used, k_process + nc + nd, self.noise_criterion
                    )
            chosen = min(
                candidates,
                key=lambda c: criterion.get(f"nc={c[0]},nd={c[1]}", 0.0),
            )
            noise = NoiseShape(*chosen)
            eta0 = etas[chosen][0]

        def joint(z: FloatArray, search: bool = True) -> JointFit:
            return joint_fit(
                data, st, noise, z, eta0, criterion, self.max_delay, search, numerics=self.numerics
            )

        if st.delay is not None or noise.size == 0:
            return joint(z0)
        # a free delay: the output-error start can sit in another basin (in closed loop oe's
        # delay is biased, by seconds with a fed-back disturbance); screen a grid of delays
        # with the cheap evaluation, then search from the best of them and from oe's start
        best = z0
        best_sse = joint(z0, search=False).sse
        # a second lag trades against the delay: screen its size too (a fraction of T)
        ratios = (None,) if st.order == 1 else (None, 0.1, 0.3, 0.6)
        for delay in np.linspace(0.0, 1.5 * max(float(z0[-1]), data.sample_time), 13):
            for ratio in ratios:
                z = z0.copy()
                z[-1] = delay
                if ratio is not None:
                    z[1] = z0[0] + math.log(ratio)
                sse = joint(z, search=False).sse
                if sse < best_sse:
                    best, best_sse = z, sse
        fits = [joint(z0)]
        if best is not z0:
            fits.append(joint(best))
        return min(fits, key=lambda fit: fit.sse)

    def _store(self, data: IOData, fit: JointFit) -> None:
        st, noise = fit.st, fit.noise
        n_z = fit.x.size - noise.size
        T, T2, delay = st.unpack(fit.x[:n_z])
        C, D = noise.polys(fit.x[n_z:])
        h = data.sample_time
        u_ref = st.u_before if st.u_before is not None else float(data.u[0])
        bounds = data.segment_bounds()
        beta = fit.beta
        self.K_, self.T_, self.T2_, self.delay_, self.T_f_ = float(beta[0]), T, T2, delay, st.T_f
        self.u_ref_ = u_ref
        # The free run needs the output level (offset, initial states) of the simulation, which
        # the prediction errors barely determine when D has a pole near 1 (a drift: the filtered
        # offset column D(1)/C(1)·1 is then nearly 0, and its estimate nearly free). So the
        # free run takes them by least squares on the unfiltered record, K and the dynamics
        # from the fit: for white or fast noise this is the fit's own level (for nc = nd = 0
        # exactly), for a drift the level the simulation is scored with. ``params_`` and
        # ``cov_`` keep the prediction-error estimates of all parameters.
        level = solve_linear(fit.Phi[:, 1:], data.y - self.K_ * fit.Phi[:, 0]).beta
        free_run = np.r_[self.K_, level]
        self.offset_ = float(level[0])
        self._state = (st, free_run, C, D)
        self.n_segments_ = data.n_segments
        self.n_samples_ = data.n_samples
        self.sample_time_ = h
        self.y_hat_ = np.asarray(fit.Phi @ free_run, dtype=float)
        self.fit_percent_ = nrmse_fit(data.y, self.y_hat_)
        # ε of the one-step predictor from that free run (= predict(data, 1, "fitted")); on the
        # samples of the criterion it differs from the minimised ε only by D/C of the level
        # difference (nothing for a drift, whose D(1) ≈ 0)
        self.residuals_ = filter_segments(D, C, data.y - self.y_hat_, bounds)
        self.one_step_fit_percent_ = nrmse_fit(data.y, data.y - self.residuals_)
        self.sse_ = fit.sse

        # Ψ = ∂ε/∂p: process columns −(D/C)·∂ŷ_p/∂p, noise columns exact (module docstring)
        values = {"T": T, "T2": T2, "delay": delay}
        names, J = jacobian(
            st, values, beta, data.u, h, u_ref, fit.Phi, bounds, numerics=self.numerics
        )
        Psi = prediction_error_jacobian(J, fit, data.y - fit.Phi @ beta, C, D, bounds)
        self.param_names_ = (*names, *noise.names)
        nl = st.nonlinear_names
        self.params_ = np.r_[self.K_, [values[name] for name in nl], beta[1:], D[1:], C[1:]]
        n_used = int(fit.used.sum())
        self.sigma_ = math.sqrt(fit.sse / max(n_used - Psi.shape[1], 1))
        self.cov_, singular = white_covariance(Psi, self.sigma_, self.numerics)
        self.covariance_method_ = "noise-model"
        sd = np.sqrt(np.diag(self.cov_))
        self.stderr_ = {"K": None, "T": None, "T2": None, "delay": None, "T_f": None}
        for name, s in zip(self.param_names_, sd, strict=True):
            if name in self.stderr_ and math.isfinite(s):
                self.stderr_[name] = float(s)
        self.fixed_ = tuple(name for name in ("T2", "delay", "T_f") if name not in nl)

        self.noise_model_ = noise_model_summary(
            C, D, noise, self.sigma_, fit.criterion, self.noise_criterion.upper()
        )

        self.warnings_ = list(data.notes)
        shown = [self.param_names_[i] for i in singular if self.param_names_[i] in MODEL_KEYS]
        if shown:
            self.warnings_.append(
                f"{', '.join(shown)} cannot be told apart from the other parameters with this "
                "log (their information is singular): no standard error or interval for them"
            )
        self.warnings_ += noise_model_warnings(C, D, noise)

    def _fitted_regression(self) -> tuple[Structure, FloatArray]:
        st, free_run, _, _ = self._state
        return st, free_run
