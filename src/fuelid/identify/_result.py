"""The settings and the result of one identification (:func:`fuelid.identify.identify`).

:class:`IdentifyOptions` holds what ``fuelid identify`` parses, :data:`METHODS` names the
methods, :class:`IdentificationResult` is what :func:`~fuelid.identify._procedure.identify`
returns (its JSON is that of ``fuelid identify --json``), and :func:`interval95` makes the 95 %
intervals it reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.model import MODEL_KEYS, Z95, ProcessModel

FloatArray = NDArray[np.float64]
Method = Literal["oe", "step-ls", "pem", "auto"]
METHODS: tuple[Method, ...] = get_args(Method)
"""The identification methods, the one registry of their names: oe, step-ls, pem and auto."""
POSITIVE_PARAMETERS = frozenset({"T", "T2", "delay", "T_f"})
"""Model parameters that cannot be negative: their 95 % intervals respect the bound 0."""
CiMethod = Literal["normal", "log", "clipped"]


@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of one identification (see ``fuelid identify --help`` for their meaning).

    The defaults assume nothing about the plant: the number of lags chosen by the rule of
    :mod:`fuelid.identify._order` (``order="auto"``: BIC and the second lag's own evidence),
    the dead time estimated, no flowmeter prior. A meter lag that is not given as
    ``flowmeter_T`` can only be estimated as a second process lag (T, T2 and T_f enter the
    model symmetrically), which ``order="auto"`` picks when the data show it.
    """

    method: Method = "oe"
    """One of :data:`METHODS`; anything else is refused."""
    order: Literal[1, 2, "auto"] = "auto"
    """Process lags for ``oe`` and ``pem``: 1, 2, or "auto" (both fitted, one kept by the rule
    of :mod:`fuelid.identify._order`). ``step-ls``
    has one fixed structure (one lag and the flowmeter prior): for it "auto" means that
    structure, and an order is not applied."""
    delay: float | Literal["auto"] | None = None
    """Fixed dead time [s], "auto" to estimate it, None: the flowmeter delay if given, else auto."""
    flowmeter_T: float | None = None
    """Flowmeter lag T_f [s], a fixed prior; None: no meter lag in the model."""
    flowmeter_delay: float | None = None
    """Flowmeter dead time [s]: the fixed total dead time when ``delay`` is None."""
    N: int | None = None
    settling_time: float | None = None
    """Prior model's 98 % settling time [s] (chooses N for step-ls)."""
    control_period: float = 1.0
    validate_split: float | None = None
    u_before: float | None = None
    covariance: Literal["auto", "white", "hac"] = "auto"
    """oe's parameter covariance: "white" σ²(JᵀJ)⁻¹, "hac" the sandwich with the residuals'
    spectrum, "auto" the sandwich whenever the residuals fail the whiteness test."""
    validation_initial: Literal["estimate", "rest"] = "estimate"
    """How a separate validation record starts: "estimate" (offset and initial state fitted to
    it, as a record that does not start at rest needs) or "rest" (at rest at its first input)."""
    full_record: bool = False
    """oe on a record over :data:`~fuelid.identify._long_record.LONG_RECORD` samples: False
    fits a copy of spread-out stretches (estimates, standard errors and tests the copy's, the
    fit % the whole record's); True searches on the copy and polishes, computes the covariance
    and tests on every sample (:mod:`fuelid.identify._long_record`). No effect on shorter
    records."""

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise FuelidError(
                f"unknown identification method {self.method!r}: use one of {', '.join(METHODS)}"
            )
        if self.covariance not in ("auto", "white", "hac"):
            raise FuelidError(f"covariance {self.covariance!r}: use auto, white or hac")
        if self.covariance != "auto" and self.method in ("step-ls", "pem"):
            raise FuelidError(
                f"the covariance choice is oe's: {self.method} has its own ("
                + ("white, from the regression" if self.method == "step-ls" else "noise-model")
                + ")"
            )

        if self.validation_initial not in ("estimate", "rest"):
            raise FuelidError(
                f"validation initial condition {self.validation_initial!r}: use estimate or rest"
            )

    def resolved_delay(self) -> float | None:
        """The fixed dead time [s], or None when it is to be estimated."""
        if self.delay == "auto":
            return None
        if self.delay is not None:
            return float(self.delay)
        return self.flowmeter_delay


def interval95(
    value: float, se: float | None, *, positive: bool = False
) -> tuple[list[float], CiMethod] | None:
    """95 % confidence interval [low, high] of one parameter, and the method that made it.

    - ``"normal"``: value ± 1.96·se, for a parameter of either sign (K);
    - ``"log"``: exp(ln value ± 1.96·se/value) for a positive parameter (T, T2, the delay): the
      normal interval of ln value, whose standard error is se/value by the delta method. It lies
      above 0, contains the estimate, and reaches further above it than below;
    - ``"clipped"``: [max(0, value − 1.96·se), value + 1.96·se] for a positive parameter whose
      estimate is 0 (a delay at its bound, where ln is undefined) or whose log interval is
      unbounded (se far larger than the estimate).

    None when there is no finite standard error (a fixed parameter).

    Examples
    --------
    >>> def show(ci):
    ...     return [round(v, 4) for v in ci[0]], ci[1]
    >>> show(interval95(13.1, 0.1))
    ([12.904, 13.296], 'normal')
    >>> show(interval95(0.5, 0.5, positive=True))  # 0.5·e^(∓1.96)
    ([0.0704, 3.5495], 'log')
    >>> show(interval95(0.0, 0.7, positive=True))
    ([0.0, 1.372], 'clipped')
    """
    if se is None or not math.isfinite(se):
        return None
    if not positive:
        return [value - Z95 * se, value + Z95 * se], "normal"
    if value > 0.0:
        with np.errstate(over="ignore"):
            spread = float(np.exp(Z95 * se / value))
        if math.isfinite(value * spread):
            return [value / spread, value * spread], "log"
    return [max(0.0, value - Z95 * se), value + Z95 * se], "clipped"


@dataclass
class IdentificationResult:
    """Everything ``identify`` found, ready for JSON (:meth:`to_json`) and plots."""

    method: Method
    model: ProcessModel
    fixed: tuple[str, ...]
    stderr: dict[str, float | None]
    cov_names: tuple[str, ...]
    cov: FloatArray
    fit_percent: float
    validation_fit_percent: float | None
    """Free-run fit on the held-out part or the validation record; None without one, or when
    it has no excitation (the reason is then among the warnings)."""
    n_samples: int
    sample_time: float
    warnings: list[str]
    time: FloatArray
    y: FloatArray
    y_hat: FloatArray
    """The model output: the free-run simulation over the whole record (fit and held-out)."""
    split_time: float | None
    diagnostics: dict[str, Any] = field(default_factory=dict)
    n_segments: int = 1
    """Contiguous segments of the record fitted (1 for a log without gaps)."""
    validation_initial: str | None = None
    """How the validation was simulated: "continued" (the held-out end of the record, simulated on
    from the fit), "estimate" or "rest" (a separate record); None without validation."""
    extra: dict[str, Any] = field(default_factory=dict)
    prediction_errors: FloatArray | None = None
    """pem's one-step prediction errors on the fitted samples (what its residual tests use);
    None for the free-run methods, whose residuals are y − y_hat."""

    def y_hat_at(self, times: FloatArray) -> FloatArray:
        """The model output at other times [output unit], interpolated within segments only.

        A record with gaps is simulated segment by segment (each restarts from its own
        state), so a value between two segments would mix the state before a gap with the
        one after it: each time takes the segment of :attr:`time` it falls in (NaN in a gap
        or in a segment this identification left out), and the value held at the segment's
        ends (step-ls's decimated samples start up to a control period after the segment).

        Examples
        --------
        >>> r = IdentificationResult(
        ...     "oe", ProcessModel(K=1.0, T=1.0), (), {}, (), np.zeros((0, 0)), 100.0, None, 4,
        ...     1.0, [], np.array([0.0, 1.0, 5.0, 6.0]), np.zeros(4), np.array([1.0, 1, 3, 3]), None
        ... )
        >>> r.y_hat_at(np.array([0.5, 3.0, 4.8, 5.5])).tolist()
        [1.0, nan, 3.0, 3.0]
        """
        times = np.asarray(times, dtype=float)
        out = np.full(times.shape, np.nan)
        edges = np.flatnonzero(np.diff(self.time) > 1.5 * self.sample_time) + 1
        for segment in np.split(np.arange(self.time.size), edges):
            t_seg = self.time[segment]
            # the segment's span and one of its sample periods each side: a decimated record's
            # samples begin and end up to one period inside the raw segment's
            reach = self.sample_time
            inside = (times >= t_seg[0] - reach) & (times <= t_seg[-1] + reach)
            out[inside] = np.interp(times[inside], t_seg, self.y_hat[segment])
        return out

    def _intervals(self) -> dict[str, tuple[list[float], CiMethod] | None]:
        values = self.model.to_json()
        return {
            key: interval95(values[key], self.stderr.get(key), positive=key in POSITIVE_PARAMETERS)
            for key in MODEL_KEYS
        }

    @property
    def lags_merged(self) -> bool:
        """Two lags the fit could not tell apart: T's and T2's intervals withheld.

        Only their combination is determined (the model's response is); the identification's
        warnings say so. True when T2 > 0 and the covariance's T and T2 rows are unknown (NaN)
        while the gain's is known.
        """
        names = tuple(self.cov_names)
        if not self.model.T2 > 0.0 or "T" not in names or "T2" not in names or "K" not in names:
            return False
        cov = np.asarray(self.cov, dtype=float)
        i, j, k = names.index("T"), names.index("T2"), names.index("K")
        return bool(np.all(np.isnan(cov[[i, j], :])) and math.isfinite(float(cov[k, k])))

    def ci95(self) -> dict[str, list[float] | None]:
        """95 % confidence intervals of the model parameters (:func:`interval95`).

        Symmetric for K; log-transformed for the positive T, T2 and delay (never below 0).
        """
        return {key: None if ci is None else ci[0] for key, ci in self._intervals().items()}

    def ci95_method(self) -> dict[str, CiMethod | None]:
        """How each interval of :meth:`ci95` was made: "normal", "log" or "clipped"."""
        return {key: None if ci is None else ci[1] for key, ci in self._intervals().items()}

    def to_json(self) -> dict[str, Any]:
        """The documented JSON object of ``fuelid identify --json`` (without provenance)."""
        return {
            "method": self.method,
            "model": {key: self.model.to_json()[key] for key in MODEL_KEYS},
            "fixed": list(self.fixed),
            "stderr": {key: self.stderr.get(key) for key in MODEL_KEYS},
            "ci95": self.ci95(),
            "ci95_method": self.ci95_method(),
            "cov": {"names": list(self.cov_names), "matrix": self.cov.tolist()},
            "fit_percent": self.fit_percent,
            "validation_fit_percent": self.validation_fit_percent,
            "validation_initial": self.validation_initial,
            "n_samples": self.n_samples,
            "sample_time": self.sample_time,
            "segments": self.n_segments,
            "diagnostics": self.diagnostics,
            "warnings": self.warnings,
            **self.extra,
        }
