"""How fuelid's fits compute: one explicit, frozen options object, :class:`Numerics`.

The same model fitted to the same record can be computed in three ways that agree to within a
small fraction of a standard error, and differ in speed:

- :data:`DEFAULT_NUMERICS`, what ``fuelid identify`` and the reports run: the nonlinear
  searches stop at tight tolerances (:data:`TIGHT_TOLERANCES`, at the rounding noise of Σε²)
  with scipy's ``least_squares`` and finite-difference Jacobians;
- :data:`WINDOW_NUMERICS`, the online windows' (issue 26): the searches stop at statistical
  tolerances (:data:`STATISTICAL_TOLERANCES`) and their Jacobians are the lags' analytic
  sensitivities (:func:`fuelid.identify._variable_projection.sensitivities`), in a
  Levenberg–Marquardt search (:mod:`fuelid.identify._search`);
- :data:`REFERENCE_NUMERICS`, the numerics as they were before issue 26, for the window
  benchmark's "today" path and ``WindowAnalyser(fast=False)``: :func:`fuelid.lti.discretise`
  through scipy's ``cont2discrete`` and ``ss2tf``, autocorrelations by one dot product per lag
  (or by FFT where the default takes dot products), (JᵀJ)⁻¹ from the SVD of J itself and the
  sandwich as a product, settling times on a grid: the same numbers to rounding, slower.

As scikit-learn passes such choices, the options are a parameter: of the estimators'
constructors (``OutputError(numerics=...)``, ``PredictionError(numerics=...)``) and of the
functions that compute differently by them (the covariances, the correlations, the searches,
the discretisation, a model's settling time), each defaulting to :data:`DEFAULT_NUMERICS`. This
module sits at the bottom of fuelid's layers so that :mod:`fuelid.lti` and :mod:`fuelid.model`
can take it too.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

__all__ = [
    "DEFAULT_NUMERICS",
    "REFERENCE_NUMERICS",
    "STATISTICAL_TOLERANCES",
    "TIGHT_TOLERANCES",
    "WINDOW_NUMERICS",
    "Numerics",
    "SearchTolerances",
]


@dataclass(frozen=True)
class SearchTolerances:
    """Where a nonlinear search stops (the meaning of scipy's ``least_squares`` tolerances).

    A step that lowers Σε² by under ``ftol`` of it, or moves the search vector by under
    ``xtol`` of its size, ends the search; so does a gradient under ``gtol``.
    """

    xtol: float
    ftol: float
    gtol: float

    def as_kwargs(self) -> dict[str, float]:
        """``{"xtol": …, "ftol": …, "gtol": …}``, the keyword arguments of ``least_squares``."""
        return {"xtol": self.xtol, "ftol": self.ftol, "gtol": self.gtol}


TIGHT_TOLERANCES = SearchTolerances(xtol=1e-10, ftol=1e-12, gtol=1e-12)
"""The default searches' stopping tolerances: at the rounding noise of Σε²."""

#: Stop when a step lowers Σε² by under 1e-8 of it, or moves the search vector (log T, log T2,
#: θ) by under 1e-6 of its size. At the optimum Σε² grows by σ²·δ² for a step of δ standard
#: errors, and Σε² ≈ N·σ², so what is left to gain then moves the estimate by about √(1e-8·N)
#: standard errors: 0.02 for a 10-minute window at 50 Hz (N = 30,000); a relative step of 1e-6
#: in T is 0.05 % of the smallest standard error seen on the windows (2·10⁻³ of T). The tight
#: tolerances (1e-12, 1e-10) sit at the rounding noise of Σε², where the search spent about a
#: third of its evaluations failing to improve (issue 26).
STATISTICAL_TOLERANCES = SearchTolerances(xtol=1e-6, ftol=1e-8, gtol=1e-10)


@dataclass(frozen=True)
class Numerics:
    """How a fit computes (module docstring): tolerances, Jacobians, the path before issue 26.

    Parameters
    ----------
    tolerances : SearchTolerances
        Where the nonlinear searches (oe's, pem's, the noise screen's) stop.
    jacobian : "differences" or "sensitivities"
        The Jacobians of the lags and the delay, in the searches and in the stored fits'
        covariances: central differences of the simulated response (with scipy's
        ``least_squares``), or the lags' analytic sensitivities (with the Levenberg–Marquardt
        search of :mod:`fuelid.identify._search`).
    reference : bool
        The numerics before issue 26 (module docstring); it also keeps the differences and
        scipy's search, whatever ``jacobian`` says.

    Examples
    --------
    >>> DEFAULT_NUMERICS.tolerances.as_kwargs(), DEFAULT_NUMERICS.jacobian
    ({'xtol': 1e-10, 'ftol': 1e-12, 'gtol': 1e-12}, 'differences')
    >>> WINDOW_NUMERICS.analytic_jacobians, REFERENCE_NUMERICS.analytic_jacobians
    (True, False)
    """

    tolerances: SearchTolerances = TIGHT_TOLERANCES
    jacobian: Literal["differences", "sensitivities"] = "differences"
    reference: bool = False

    def __post_init__(self) -> None:
        if self.jacobian not in ("differences", "sensitivities"):
            raise ValueError(
                f"jacobian must be 'differences' or 'sensitivities', got {self.jacobian!r}"
            )

    @property
    def analytic_jacobians(self) -> bool:
        """True when the Jacobians are the lags' sensitivities (and the search Moré's LM)."""
        return self.jacobian == "sensitivities" and not self.reference

    def statistical(self) -> Numerics:
        """These numerics with the windows' search: statistical tolerances, analytic Jacobians.

        What a long record's search on its copy runs (:mod:`fuelid.identify._long_record`); the
        ``reference`` choice is kept.
        """
        return replace(self, tolerances=STATISTICAL_TOLERANCES, jacobian="sensitivities")


DEFAULT_NUMERICS = Numerics()
"""``fuelid identify``'s numerics: tight tolerances, finite differences."""
WINDOW_NUMERICS = DEFAULT_NUMERICS.statistical()
"""The online windows' numerics: statistical tolerances, the lags' analytic sensitivities."""
REFERENCE_NUMERICS = Numerics(reference=True)
"""The numerics before issue 26: ``WindowAnalyser(fast=False)``, the benchmark's "today"."""
