"""Tracking of the loop gain K against fuel temperature from accepted identification windows.

Every accepted window of the online service gives one :class:`GainObservation`: its time, mean
fuel temperature, mean command, the identified static gain K [(L/min)/V] and its standard error.
K depends on the operating point as much as on the temperature (on the reference plant it falls
about 13 % from 1.25 to 4.75 V and about 11 % from −20 to 50 °C), so with a plant model
:class:`KTracker` tracks the ratio

    r = K_id / K_plant(u, T),    se_r = se_K / K_plant(u, T)

of the identified gain to the plant model's linearised gain at the window's command and
temperature, against temperature, as the weighted least-squares line

    r(T) = a + b·(T − T_ref),    weights w = 1/se_r²,

which removes the known physics and leaves what the model does not know (pump wear, a wrong
viscosity curve, a drifting meter). Without a plant model it tracks K itself per command band
(default 1 V wide), one such line per band.

Uncertainty: the parameter covariance is (XᵀWX)⁻¹. When the residuals scatter more than the
windows' standard errors explain (window-to-window variation that one window's covariance cannot
see), the covariance is multiplied by the Birge ratio squared, max(1, χ²/dof) with
χ² = Σ w·(r − r̂)² and dof = n − p (Birge 1932; the multiplicative, "scale-factor" treatment of
the Particle Data Group), not by an additive random-effects variance. Predictions propagate the
covariance linearly: var r̂(T) = xᵀ·cov·x with x = (1, T − T_ref), and K = r̂·K_plant(u, T) with
K_plant taken as exact.

Old windows may be down-weighted with a forgetting time τ: a window of age Δt (from the newest
observation) has its variance multiplied by exp(Δt/τ), i.e. its weight by exp(−Δt/τ).

Refusals: fewer than two observations raise :class:`TrackingError`; a temperature spread below
``min_spread_C`` fits the constant ratio only (``slope_`` None, ``slope_estimated`` False, with the
reason in ``note``).

References
----------
R. T. Birge, "The calculation of errors by the method of least squares", Phys. Rev. 40 (1932)
207–227. Particle Data Group, *Review of Particle Physics*, "Introduction: averaging procedures"
(scale factor S). L. Ljung, *System Identification* (2nd ed., Prentice Hall, 1999), §11.2
(forgetting factors).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError, NotFittedError
from fuelid.params import Params
from fuelid.plant import PlantConfig, linearise
from fuelid.units import celsius_to_kelvin

FloatArray = NDArray[np.float64]
PlantGain = Callable[[float, float], float]
"""A plant model's linearised gain K [(L/min)/V] at command u [V] and fuel temperature [°C]."""

MIN_SPREAD_C = 2.0
"""Smallest temperature spread (max − min) over which a slope is estimated [°C]."""
BAND_WIDTH_V = 1.0
"""Width of a command band when there is no plant model [V]."""

TRACKING_UNITS = {
    "T_ref": "degC",
    "intercept": "1 (ratio) or (L/min)/V (band)",
    "slope": "1/degC (ratio) or (L/min)/V/degC (band)",
    "temperature_range": "degC",
    "forgetting_time": "s",
    "band": "V",
    "command": "V",
}
"""Units of the numbers in :meth:`KTracker.to_json`."""


class TrackingError(DataError):
    """Too few, or unusable, gain observations to track K against temperature."""


@dataclass(frozen=True)
class GainObservation:
    """One accepted identification window, as the K(T) tracker sees it."""

    time: float
    """End of the window [s since the epoch, UTC]."""
    T_fuel_C: float
    """Mean fuel temperature over the window [°C]."""
    u: float
    """Mean command over the window [V]."""
    K: float
    """Identified static gain [(L/min)/V]."""
    se_K: float
    """Standard error of ``K`` [(L/min)/V]."""
    K_plant: float | None = None
    """The plant model's linearised gain at (``u``, ``T_fuel_C``) [(L/min)/V], if known."""


@dataclass(frozen=True)
class LineFit:
    """A weighted least-squares line y(T) = a + b·(T − T_ref) with its covariance."""

    intercept: float
    """a: the value at ``T_ref`` [ratio or (L/min)/V]."""
    slope: float | None
    """b [per °C]; None when the temperature spread was too small to estimate it."""
    T_ref: float
    """Reference temperature: the weighted mean of the observations' temperatures [°C]."""
    cov: FloatArray
    """Covariance of (a, b), or 1×1 of a alone, Birge inflation included."""
    chi2: float
    """Σ w·residual² before inflation [-]."""
    dof: int
    """Degrees of freedom n − p [-]."""
    n: int
    """Number of observations [-]."""
    T_min: float
    """Lowest observed temperature [°C]."""
    T_max: float
    """Highest observed temperature [°C]."""
    note: str = ""
    """Why the slope is missing or the inflation could not be estimated, if so."""

    @property
    def birge_ratio(self) -> float:
        """√(χ²/dof) [-]; NaN without degrees of freedom."""
        return math.sqrt(self.chi2 / self.dof) if self.dof > 0 else math.nan

    @property
    def inflation(self) -> float:
        """The factor applied to the covariance: max(1, χ²/dof) [-]."""
        return max(1.0, self.chi2 / self.dof) if self.dof > 0 else 1.0

    @property
    def se(self) -> tuple[float, float | None]:
        """Standard errors of (a, b); b's None without a slope."""
        sa = math.sqrt(float(self.cov[0, 0]))
        return sa, (math.sqrt(float(self.cov[1, 1])) if self.slope is not None else None)

    def predict(self, T_C: float) -> tuple[float, float]:
        """Value and standard error at fuel temperature ``T_C`` [°C], propagated linearly."""
        if self.slope is None:
            return self.intercept, math.sqrt(float(self.cov[0, 0]))
        x = np.array([1.0, T_C - self.T_ref])
        return self.intercept + self.slope * (T_C - self.T_ref), math.sqrt(float(x @ self.cov @ x))

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary (NaN as None)."""
        sa, sb = self.se
        return {
            "intercept": self.intercept,
            "slope": self.slope,
            "se_intercept": sa,
            "se_slope": sb,
            "T_ref": self.T_ref,
            "cov": self.cov.tolist(),
            "chi2": self.chi2,
            "dof": self.dof,
            "birge_ratio": None if math.isnan(self.birge_ratio) else self.birge_ratio,
            "inflation": self.inflation,
            "n": self.n,
            "temperature_range": [self.T_min, self.T_max],
            "slope_estimated": self.slope is not None,
            "note": self.note,
        }


def fit_line(T_C: FloatArray, y: FloatArray, var: FloatArray, min_spread_C: float) -> LineFit:
    """Weighted least-squares line with Birge-ratio inflation.

    Parameters
    ----------
    T_C : ndarray
        Fuel temperatures [°C].
    y : ndarray
        Observed values (ratio [-] or K [(L/min)/V]).
    var : ndarray
        Their variances (forgetting included) [y's unit squared].
    min_spread_C : float
        Smallest max − min temperature spread for a slope [°C].

    Returns
    -------
    LineFit

    Examples
    --------
    >>> T = np.array([0.0, 10.0, 20.0, 30.0])
    >>> f = fit_line(T, 1.0 + 0.01 * T, np.full(4, 1e-4), 2.0)
    >>> round(f.intercept, 6), round(f.slope, 6), f.T_ref
    (1.15, 0.01, 15.0)
    """
    n = int(y.size)
    if n < 2:
        raise TrackingError(f"K(T) tracking needs at least 2 observations, got {n}")
    w = 1.0 / var
    T_ref = float(np.sum(w * T_C) / np.sum(w))
    spread = float(np.max(T_C) - np.min(T_C))
    note = ""
    if spread < min_spread_C:
        X = np.ones((n, 1))
        note = (
            f"temperature spread {spread:.2f} degC < {min_spread_C:g} degC: "
            "constant fitted, no slope"
        )
    else:
        X = np.column_stack([np.ones(n), T_C - T_ref])
    p = X.shape[1]
    cov = np.linalg.inv(X.T @ (w[:, None] * X))
    beta = cov @ (X.T @ (w * y))
    resid = y - X @ beta
    chi2 = float(np.sum(w * resid**2))
    dof = n - p
    if dof > 0:
        cov = cov * max(1.0, chi2 / dof)
    else:
        extra = "no degrees of freedom left: between-window scatter not estimable"
        note = f"{note}; {extra}" if note else extra
    return LineFit(
        intercept=float(beta[0]),
        slope=float(beta[1]) if p == 2 else None,
        T_ref=T_ref,
        cov=np.asarray(cov, dtype=np.float64),
        chi2=chi2,
        dof=dof,
        n=n,
        T_min=float(np.min(T_C)),
        T_max=float(np.max(T_C)),
        note=note,
    )


def plant_gain_function(config: PlantConfig) -> PlantGain:
    """The plant model's linearised gain as a function of command [V] and fuel temperature [°C].

    The static gain −C·A⁻¹·B + D of the plant linearised at (u, T), the K that
    ``fuelid plant info`` prints (its equivalent model keeps the linear plant's static gain).

    Parameters
    ----------
    config : PlantConfig
        The plant.

    Returns
    -------
    callable
        ``k(u_V, T_C) -> K`` with u in V, T in °C and K in (L/min)/V.

    Examples
    --------
    >>> from fuelid.plant import load_plant_config
    >>> k = plant_gain_function(load_plant_config())
    >>> k(1.25, 20.0) > k(4.75, 20.0) > 0.0
    True
    """

    def k_plant(u_V: float, T_C: float) -> float:
        return linearise(config, u_V, celsius_to_kelvin(T_C)).static_gain

    return k_plant


class KTracker(Params):
    """Loop gain K against fuel temperature, as a ratio to the plant model or per command band.

    An estimator as fuelid's others are: the settings are stored unchanged by ``__init__``,
    :meth:`fit` returns ``self``, and the fitted attributes (ending in ``_``) exist only after
    a fit that succeeded (before, or after a refused fit, they raise
    :class:`~fuelid.errors.NotFittedError`). :meth:`update` refits with one more observation;
    the observations it adds to are kept even when a fit is refused (the first window alone
    cannot be tracked, the second with it can).

    Parameters
    ----------
    k_plant : callable, optional
        ``k_plant(u_V, T_C) -> K`` [(L/min)/V] (see :func:`plant_gain_function`). Without it the
        ratio is still tracked when every observation carries ``K_plant``, otherwise K is
        tracked per command band.
    forgetting_time_s : float, optional
        τ [s]: an observation Δt older than the newest has its variance multiplied by exp(Δt/τ).
        None (default) weighs all observations alike.
    min_spread_C : float
        Smallest temperature spread for a slope [°C] (:data:`MIN_SPREAD_C`).
    band_width_V : float
        Command band width without a plant model [V] (:data:`BAND_WIDTH_V`).
    max_observations : int, optional
        Keep only the newest this many observations (bounded memory in a long-running service).

    Attributes
    ----------
    observations_ : list of GainObservation
        The observations of the fit (the newest ``max_observations``).
    mode_ : str
        ``"ratio"`` or ``"band"``.
    fit_ : LineFit or None
        The ratio line (ratio mode).
    bands_ : dict
        Band index → LineFit or None (fewer than 2 observations in the band), band mode.

    Examples
    --------
    >>> obs = [GainObservation(60.0 * i, t, 3.0, 0.9 * 13.0, 0.1, 13.0) for i, t in
    ...        enumerate([0.0, 10.0, 20.0, 30.0])]
    >>> tr = KTracker().fit(obs)
    >>> K, se = tr.predict(25.0, K_plant=13.0)
    >>> round(K, 6), tr.mode_
    (11.7, 'ratio')
    >>> hasattr(KTracker(), "mode_")
    False
    """

    _SETTINGS = ("k_plant", "forgetting_time_s", "min_spread_C", "band_width_V", "max_observations")
    _FITTED = ("observations_", "mode_", "fit_", "bands_")
    # the fitted attributes: annotated, never assigned on the class (absent until a fit)
    observations_: list[GainObservation]
    mode_: str
    fit_: LineFit | None
    bands_: dict[int, LineFit | None]

    def __init__(
        self,
        k_plant: PlantGain | None = None,
        forgetting_time_s: float | None = None,
        min_spread_C: float = MIN_SPREAD_C,
        band_width_V: float = BAND_WIDTH_V,
        max_observations: int | None = None,
    ) -> None:
        self.k_plant = k_plant
        self.forgetting_time_s = forgetting_time_s
        self.min_spread_C = min_spread_C
        self.band_width_V = band_width_V
        self.max_observations = max_observations
        self._held: list[GainObservation] = []

    if not TYPE_CHECKING:  # hidden from mypy, which would otherwise accept any attribute name

        def __getattr__(self, name: str) -> Any:
            # called only when normal lookup fails: a fitted attribute before a fit
            if name in KTracker._FITTED:
                raise NotFittedError(f"KTracker is not fitted: {name} exists only after fit()")
            raise AttributeError(f"'KTracker' object has no attribute {name!r}")

    @property
    def observations(self) -> tuple[GainObservation, ...]:
        """The observations held: those of the last fit, or of the last fit refused [-]."""
        return tuple(self._held)

    # --- fitting ----------------------------------------------------------------------------------

    def fit(self, observations: Iterable[GainObservation]) -> KTracker:
        """Fit on ``observations`` (replacing any earlier ones); returns ``self``.

        Raises
        ------
        TrackingError
            An observation with a bad value, fewer than two observations, or no command band
            with two; the tracker is then not fitted.
        """
        for name in self._FITTED:
            self.__dict__.pop(name, None)
        self._held = [self._checked(obs) for obs in observations]
        if self.max_observations is not None:
            self._held = self._held[-self.max_observations :]
        fitted = self._fitted(list(self._held))
        self.__dict__.update(fitted)
        return self

    def update(self, obs: GainObservation) -> KTracker:
        """Add one observation to those held and refit; returns ``self``."""
        checked = self._checked(obs)
        return self.fit([*self._held, checked])

    def _checked(self, obs: GainObservation) -> GainObservation:
        values = (obs.time, obs.T_fuel_C, obs.u, obs.K, obs.se_K)
        if not all(math.isfinite(v) for v in values):
            raise TrackingError(f"gain observation with a non-finite value: {obs}")
        if obs.K <= 0.0 or obs.se_K <= 0.0:
            raise TrackingError(f"gain observation needs K > 0 and se_K > 0, got {obs}")
        if obs.K_plant is None and self.k_plant is not None:
            obs = GainObservation(
                obs.time, obs.T_fuel_C, obs.u, obs.K, obs.se_K, self.k_plant(obs.u, obs.T_fuel_C)
            )
        if obs.K_plant is not None and not (math.isfinite(obs.K_plant) and obs.K_plant > 0.0):
            raise TrackingError(f"plant gain must be finite and > 0, got {obs.K_plant}")
        return obs

    def _fitted(self, obs: list[GainObservation]) -> dict[str, Any]:
        """The fitted attributes from ``obs``: set all at once, or none (refused)."""
        if len(obs) < 2:
            raise TrackingError(f"K(T) tracking needs at least 2 observations, got {len(obs)}")
        with_plant = [o.K_plant is not None for o in obs]
        if any(with_plant) and not all(with_plant):
            raise TrackingError("some observations carry K_plant and some do not: pass k_plant")
        t = np.array([o.time for o in obs])
        T = np.array([o.T_fuel_C for o in obs])
        K = np.array([o.K for o in obs])
        se = np.array([o.se_K for o in obs])
        age_factor = (
            np.ones(len(obs))
            if self.forgetting_time_s is None
            else np.exp((np.max(t) - t) / self.forgetting_time_s)
        )
        if all(with_plant):
            Kp = np.array([o.K_plant for o in obs], dtype=float)
            line = fit_line(T, K / Kp, (se / Kp) ** 2 * age_factor, self.min_spread_C)
            return {"observations_": obs, "mode_": "ratio", "fit_": line, "bands_": {}}
        idx = np.floor(np.array([o.u for o in obs]) / self.band_width_V).astype(int)
        bands: dict[int, LineFit | None] = {}
        for b in sorted(set(idx.tolist())):
            m = idx == b
            bands[b] = (
                fit_line(T[m], K[m], se[m] ** 2 * age_factor[m], self.min_spread_C)
                if np.count_nonzero(m) >= 2
                else None
            )
        if all(f is None for f in bands.values()):
            raise TrackingError("no command band holds at least 2 observations")
        return {"observations_": obs, "mode_": "band", "fit_": None, "bands_": bands}

    # --- using the fit ----------------------------------------------------------------------------

    def _require_fit(self) -> None:
        if "mode_" not in vars(self):
            raise NotFittedError("KTracker is not fitted: call fit() or update() first")

    def _mean_command(self) -> float:
        return float(np.mean([o.u for o in self.observations_]))

    def predict_ratio(self, T_C: float) -> tuple[float, float]:
        """Ratio K/K_plant and its standard error at fuel temperature ``T_C`` [°C] (ratio mode)."""
        self._require_fit()
        if self.fit_ is None:
            raise TrackingError("no plant model: the ratio K/K_plant is not tracked")
        return self.fit_.predict(T_C)

    def predict(
        self, T_C: float, u: float | None = None, K_plant: float | None = None
    ) -> tuple[float, float]:
        """K [(L/min)/V] and its standard error at fuel temperature ``T_C`` [°C] and command ``u``.

        Parameters
        ----------
        T_C : float
            Fuel temperature [°C].
        u : float, optional
            Command [V]; default the mean command of the observations.
        K_plant : float, optional
            The plant model's gain at (u, T) [(L/min)/V]; computed with ``k_plant`` if not given
            (ratio mode).

        Returns
        -------
        tuple of float
            (K, se) [(L/min)/V]; se from the fit covariance only (K_plant is taken as exact).
        """
        self._require_fit()
        command = self._mean_command() if u is None else u
        if self.fit_ is not None:
            if K_plant is None:
                if self.k_plant is None:
                    raise TrackingError("predicting K in ratio mode needs K_plant or k_plant")
                K_plant = self.k_plant(command, T_C)
            r, se_r = self.fit_.predict(T_C)
            return r * K_plant, se_r * K_plant
        band = math.floor(command / self.band_width_V)
        line = self.bands_.get(band)
        if line is None:
            raise TrackingError(f"no fitted command band holds u = {command:g} V")
        return line.predict(T_C)

    def drift(
        self, T_C: float, K_tuned: float, u: float | None = None, K_plant: float | None = None
    ) -> tuple[float, float]:
        """How far the loop has moved from the model the current gains were tuned for.

        Parameters
        ----------
        T_C : float
            Fuel temperature [°C].
        K_tuned : float
            Gain of the model the current PI gains were tuned for [(L/min)/V].
        u, K_plant : float, optional
            As in :meth:`predict`.

        Returns
        -------
        tuple of float
            (K_now/K_tuned, its standard error) [-]; 1 means no drift.
        """
        if not K_tuned > 0.0:
            raise TrackingError(f"K_tuned must be > 0, got {K_tuned}")
        K, se = self.predict(T_C, u, K_plant)
        return K / K_tuned, se / K_tuned

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary of the fit (settings, the line(s), units)."""
        self._require_fit()
        out: dict[str, Any] = {
            "mode": self.mode_,
            "n": len(self.observations_),
            "forgetting_time": self.forgetting_time_s,
            "min_spread": self.min_spread_C,
            "covariance_inflation": "birge: cov * max(1, chi2/dof)",
            "units": TRACKING_UNITS,
        }
        if self.fit_ is not None:
            out["ratio"] = self.fit_.to_json()
        else:
            out["band_width"] = self.band_width_V
            out["bands"] = [
                {
                    "band": [b * self.band_width_V, (b + 1) * self.band_width_V],
                    "fit": None if f is None else f.to_json(),
                }
                for b, f in self.bands_.items()
            ]
        return out
