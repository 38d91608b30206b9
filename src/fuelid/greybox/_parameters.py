"""Named model parameters: start values, bounds, fixed flags, and the space the optimiser sees.

A parameter that must be positive (lower bound ≥ 0 and a positive start) is estimated as its
logarithm: steps are relative, the positivity bound can never be crossed, and the 95 % interval
``exp(log θ ± 1.96·σ)`` stays positive and is asymmetric as a ratio estimate's should be. Any
other parameter is estimated as itself, inside its bounds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import ConfigError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ParameterSpec:
    """One model parameter.

    Attributes
    ----------
    name : str
        Its name (a key of the mapping the model functions receive).
    value : float
        Start value of the fit, or the value used when ``fixed``.
    lower, upper : float or None
        Bounds (None: unbounded on that side).
    fixed : bool
        Held at ``value``, not estimated.
    """

    name: str
    value: float
    lower: float | None = None
    upper: float | None = None
    fixed: bool = False

    def __post_init__(self) -> None:
        if not math.isfinite(self.value):
            raise ConfigError(f"parameter {self.name}: start value {self.value!r} is not finite")
        lower = -math.inf if self.lower is None else self.lower
        upper = math.inf if self.upper is None else self.upper
        if not lower < upper:
            raise ConfigError(f"parameter {self.name}: lower bound {lower:g} ≥ upper {upper:g}")
        if not lower <= self.value <= upper:
            raise ConfigError(
                f"parameter {self.name}: start value {self.value:g} lies outside its bounds "
                f"[{lower:g}, {upper:g}]"
            )

    @property
    def log_scale(self) -> bool:
        """Estimated as log θ: the parameter is bounded below by ≥ 0 and starts above 0."""
        return self.lower is not None and self.lower >= 0.0 and self.value > 0.0


def parameter_specs(
    specs: Sequence[ParameterSpec],
    fixed: Sequence[str] = (),
    free: Sequence[str] = (),
    values: Mapping[str, float] | None = None,
) -> tuple[ParameterSpec, ...]:
    """Apply a caller's overrides (fix some, free some, new start values) to a parameter list.

    Raises
    ------
    ConfigError
        For a name that is not a parameter (the valid names are listed), or one both fixed and
        freed.
    """
    by_name = {spec.name: spec for spec in specs}
    for name in [*fixed, *free, *(values or {})]:
        if name not in by_name:
            raise ConfigError(f"unknown parameter {name!r}; valid: {', '.join(by_name)}")
    both = sorted(set(fixed) & set(free))
    if both:
        raise ConfigError(f"parameter(s) {', '.join(both)} both fixed and freed: choose one")
    out = []
    for spec in specs:
        if spec.name in fixed:
            spec = replace(spec, fixed=True)
        elif spec.name in free:
            spec = replace(spec, fixed=False)
        if values and spec.name in values:
            spec = replace(spec, value=float(values[spec.name]))
        out.append(spec)
    return tuple(out)


@dataclass(frozen=True)
class ParameterMap:
    """The free parameters' transform between natural units θ and the optimiser's φ."""

    specs: tuple[ParameterSpec, ...]

    @property
    def free(self) -> tuple[ParameterSpec, ...]:
        """The estimated parameters, in order."""
        return tuple(spec for spec in self.specs if not spec.fixed)

    @property
    def free_names(self) -> tuple[str, ...]:
        """Names of the estimated parameters."""
        return tuple(spec.name for spec in self.free)

    @property
    def log_mask(self) -> NDArray[np.bool_]:
        """True where a free parameter is estimated in log space."""
        return np.array([spec.log_scale for spec in self.free], dtype=bool)

    def start(self) -> FloatArray:
        """φ at the start values."""
        return self.to_phi(np.array([spec.value for spec in self.free], dtype=float))

    def to_phi(self, theta: FloatArray) -> FloatArray:
        """φ from the free parameters' natural values."""
        mask = self.log_mask
        phi = np.array(theta, dtype=float)
        # a φ far out in log space underflows to θ = 0 (to_theta): back to the smallest φ that
        # gives a positive θ, not log 0 = −inf, which no fit can start from
        phi[mask] = np.log(np.maximum(phi[mask], np.finfo(float).tiny))
        return phi

    def to_theta(self, phi: FloatArray) -> FloatArray:
        """The free parameters' natural values from φ."""
        mask = self.log_mask
        theta = np.array(phi, dtype=float)
        # a trial step far out in log space overflows to inf: a point the model cannot be
        # simulated at (the fit steps back), not a warning for the user
        with np.errstate(over="ignore"):
            theta[mask] = np.exp(theta[mask])
        return theta

    def dtheta_dphi(self, phi: FloatArray) -> FloatArray:
        """∂θ/∂φ per free parameter: θ in log space, 1 otherwise."""
        return np.where(self.log_mask, self.to_theta(phi), 1.0)

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        """Bounds on φ (log-transformed where the parameter is)."""
        lower, upper = [], []
        for spec in self.free:
            lo = -math.inf if spec.lower is None else spec.lower
            hi = math.inf if spec.upper is None else spec.upper
            if spec.log_scale:
                lo = math.log(lo) if lo > 0.0 else -math.inf
                hi = math.log(hi) if math.isfinite(hi) else math.inf
            lower.append(lo)
            upper.append(hi)
        return np.array(lower), np.array(upper)

    def values(self, phi: FloatArray) -> dict[str, float]:
        """Every parameter's value (fixed ones at their value) for φ."""
        theta = iter(self.to_theta(phi).tolist())
        return {spec.name: spec.value if spec.fixed else next(theta) for spec in self.specs}
