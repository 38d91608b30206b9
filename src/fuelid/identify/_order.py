"""How many process lags a log supports: the one order rule of oe, pem and the online windows.

With ``order="auto"`` an estimator fits one lag and two lags and hands both fits to
:func:`choose_order`. The second lag is kept only when all of these hold:

1. **BIC prefers it.** BIC = N·ln(Σε²/N) + k·ln N (Schwarz 1978). BIC is consistent: as the
   record grows, the probability of keeping a lag that is not there goes to 0, while AIC's
   penalty of 2 per parameter keeps one in about one white-noise record in six whatever its
   length (Shibata 1976). A second lag costs two parameters (the lag and its initial-state
   amplitude), so on a 300 s record at 50 Hz (N = 15 000) the fit must improve N·ln(Σε²) by
   2·ln N ≈ 19: a χ²(2) exceeds that with probability 7·10⁻⁵.
2. **It is longer than the sample period.** A lag shorter than h is invisible between two
   samples: what it fits is the noise of the first samples after a step.
3. **Its 95 % interval excludes zero**: lag − 1.96·se(lag) > 0, with the fit's own standard
   error (the HAC sandwich when the residuals are coloured, so coloured noise, which inflates
   the BIC's improvement, does not pass here too).
4. **With no meter lag given, the two lags are told apart** (|T − T2| > 1.96·se(T − T2), and
   |corr(T, T2)| ≤ :data:`LAGS_NOT_SEPARATED`: beyond it the separate intervals are withheld, and
   the pair is never told apart, the split undetermined with or without a meter lag), **or
   BIC's preference is very strong** (by :data:`BIC_CLOSE` or more). The meter's lag is then one
   of the two fitted lags. Two lags the data cannot separate, with little to choose between the
   orders, are one lag's worth of information spent on two parameters; but when one lag fits
   decisively worse (two similar lags in series, a slow meter), dropping the second would bias
   K, T and the delay: the pair is kept and its split said to be undetermined (the intervals
   are then conditional on the structure, below).

Whatever the choice, the result lists every order compared (its BIC, parameters and standard
errors) and why one was kept; and it says when the intervals are **conditional on the
structure** (:attr:`OrderChoice.conditional`): when the chosen fit's lags and delay trade
against each other (|correlation| > :data:`TRADE_CORRELATION`), or when BIC separates the
orders by less than :data:`BIC_CLOSE` (Kass & Raftery 1995: below 10 the evidence is not "very
strong"). The standard errors then hold within the structure only; the structures the data
cannot tell apart are listed with their parameters.

References
----------
G. Schwarz, "Estimating the dimension of a model", *Ann. Statist.* 6 (1978) 461–464.
R. Shibata, "Selection of the order of an autoregressive model by Akaike's information
criterion", *Biometrika* 63 (1976) 117–126.
R. E. Kass and A. E. Raftery, "Bayes factors", *J. Amer. Statist. Assoc.* 90 (1995) 773–795.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.model import MODEL_KEYS, Z95, ProcessModel

FloatArray = NDArray[np.float64]

BIC_CLOSE = 10.0
"""Orders whose BIC differ by less than this are ones the data cannot firmly tell apart [-]."""
TRADE_CORRELATION = 0.95
"""|correlation| between two of T, T2 and the delay above which they trade against each other."""
DYNAMIC_PARAMETERS = ("T", "T2", "delay")
LAGS_NOT_SEPARATED = 0.999
"""|corr(T, T2)| above which the two lags are not separately determined: their separate
intervals are withheld, and the order rule does not count them as told apart."""


def bic(sse: float, n: int, k: int) -> float:
    """Bayesian information criterion N·ln(SSE/N) + k·ln N of a least-squares fit.

    Parameters
    ----------
    sse : float
        Sum of squared residuals (or prediction errors) [output unit²].
    n : int
        Samples in the sum [-].
    k : int
        Estimated parameters [-].

    Examples
    --------
    >>> round(bic(1.0, 100, 2), 3)  # 100·ln(0.01) + 2·ln 100
    -451.307
    """
    return n * math.log(max(sse, 1e-300) / n) + k * math.log(n)


@dataclass(frozen=True)
class Candidate:
    """One fitted structure: its order, criterion, parameters and their covariance."""

    order: int
    bic: float
    n_params: int
    model: ProcessModel
    stderr: dict[str, float | None]
    names: tuple[str, ...]
    cov: FloatArray
    stderr_computed: bool = True
    """False for a structure whose covariance was not computed (a long record's order the
    rule did not need it for: :meth:`without_covariance`); its ``stderr`` are then None."""

    @classmethod
    def without_covariance(
        cls,
        order: int,
        criterion: float,
        model: ProcessModel,
        names: tuple[str, ...],
        n_params: int,
    ) -> Candidate:
        """A fitted structure whose covariance is not computed: NaN, and every stderr None.

        What the order rule reads of a structure it does not keep, or keeps on BIC alone, is
        its BIC; the covariance only of a two-lag fit BIC prefers (conditions 3 and 4) and of
        the one kept (the trades). On a long record (:mod:`fuelid.identify._long_record`) the
        estimator computes it for those only: on a day at 50 Hz one costs a second and a
        quarter of a gigabyte. ``names``: the free parameters the covariance would be of.
        """
        return cls(
            order=order,
            bic=criterion,
            n_params=n_params,
            model=model,
            stderr=dict.fromkeys(MODEL_KEYS),
            names=names,
            cov=np.full((len(names), len(names)), np.nan),
            stderr_computed=False,
        )

    @classmethod
    def of_fit(cls, estimator: Any, order: int, criterion: float) -> Candidate:
        """A fitted estimator's stored fit as a candidate of ``order`` with BIC ``criterion``.

        Reads ``model_``, ``stderr_``, ``param_names_``, ``params_`` and ``cov_``.
        """
        return cls(
            order=order,
            bic=criterion,
            n_params=estimator.params_.size,
            model=estimator.model_,
            stderr=dict(estimator.stderr_),
            names=estimator.param_names_,
            cov=estimator.cov_,
        )

    def cov_of(self, a: str, b: str) -> float:
        """Covariance of two named parameters (nan when either is not estimated)."""
        if a not in self.names or b not in self.names:
            return math.nan
        return float(self.cov[self.names.index(a), self.names.index(b)])

    def to_json(self, best_bic: float) -> dict[str, Any]:
        """The candidate as the JSON ``structure.compared`` lists it."""
        values = self.model.to_json()
        return {
            "order": self.order,
            "bic": self.bic,
            "delta_bic": self.bic - best_bic,
            "n_params": self.n_params,
            "model": {key: values[key] for key in MODEL_KEYS},
            "stderr": {key: self.stderr.get(key) for key in MODEL_KEYS},
            "stderr_computed": self.stderr_computed,
        }


@dataclass
class OrderChoice:
    """The order kept, the orders compared, and what the intervals are conditional on."""

    chosen: int
    reason: str
    candidates: tuple[Candidate, ...]
    trades: list[tuple[str, str, float]] = field(default_factory=list)
    """Pairs of T, T2, delay in the chosen fit with |correlation| > TRADE_CORRELATION."""
    split_undetermined: bool = False
    """Two lags kept that the data do not tell apart: with no meter lag given, not told apart
    (condition 4); in any case, correlated beyond ±:data:`LAGS_NOT_SEPARATED`."""

    @property
    def chosen_candidate(self) -> Candidate:
        """The candidate of the kept order."""
        return next(c for c in self.candidates if c.order == self.chosen)

    misfit: bool = False
    """The residuals are coloured by the model's misfit (white where the output has settled):
    the intervals count the noise, not the misfit's bias (set by the estimator)."""

    @property
    def close(self) -> tuple[Candidate, ...]:
        """The orders the data do not rule out.

        Within :data:`BIC_CLOSE` of the kept one's BIC, or preferred by BIC and not kept by the
        rule (the rule's objection is no evidence against the structure's fit).
        """
        kept = self.chosen_candidate.bic
        return tuple(
            c
            for c in self.candidates
            if c.order != self.chosen and (abs(c.bic - kept) < BIC_CLOSE or c.bic < kept)
        )

    @property
    def conditional(self) -> bool:
        """Whether the intervals hold only within the chosen structure."""
        return bool(self.trades or self.close or self.split_undetermined or self.misfit)

    def conditional_note(self) -> str | None:
        """The sentence saying why the intervals are conditional on the structure, or None."""
        if not self.conditional:
            return None
        why = []
        if self.trades:
            pairs = ", ".join(f"{a} and {b} ({r:+.2f})" for a, b, r in self.trades)
            why.append(f"{pairs} trade against each other")
        if self.split_undetermined:
            why.append("the two lags are not told apart")
        for other in self.close:
            gap = other.bic - self.chosen_candidate.bic
            if abs(gap) < BIC_CLOSE:
                why.append(
                    f"BIC separates {_lags(self.chosen)} from {_lags(other.order)} by only "
                    f"{abs(gap):.1f} (< {BIC_CLOSE:g})"
                )
            else:
                why.append(
                    f"BIC prefers {_lags(other.order)} by {-gap:.1f}, which the rule did not keep"
                )
        if self.misfit:
            why.append(
                "the residuals are coloured by the model's misfit after command changes, a bias "
                "the intervals (which count the noise) do not hold"
            )
        alternatives = "; ".join(_describe(c) for c in self.close)
        text = (
            f"the intervals are conditional on the structure ({_lags(self.chosen)}): "
            f"{'; '.join(why)}"
        )
        if alternatives:
            text += f"; the data do not rule out {alternatives}"
        if (self.trades or self.split_undetermined) and not self.close:
            text += (
                "; a lag the model lacks, or a wrong prior, moves them together beyond their "
                "intervals, and a meter prior (--flowmeter-T, --flowmeter-delay) fixes the split"
            )
        return text

    def to_json(self) -> dict[str, Any]:
        """The JSON ``structure`` object (documented in docs/explanation/identification.md)."""
        best = min(c.bic for c in self.candidates)
        return {
            "criterion": "BIC",
            "compared": [c.to_json(best) for c in self.candidates],
            "chosen_order": self.chosen,
            "reason": self.reason,
            "conditional": self.conditional,
            "trades": [{"a": a, "b": b, "correlation": r} for a, b, r in self.trades],
            "split_undetermined": self.split_undetermined,
            "indistinct": [c.to_json(best) for c in self.close],
        }


def _lags(order: int) -> str:
    return "one lag" if order == 1 else "two lags"


def _describe(c: Candidate) -> str:
    m = c.model
    lags = f"T {m.T:.4g} s" + (f", T2 {m.T2:.4g} s" if m.T2 > 0.0 else "")
    return f"{_lags(c.order)} (K {m.K:.4g}, {lags}, delay {m.delay:.4g} s)"


def _trades(c: Candidate) -> list[tuple[str, str, float]]:
    out = []
    present = [name for name in DYNAMIC_PARAMETERS if name in c.names]
    for i, a in enumerate(present):
        for b in present[i + 1 :]:
            va, vb, cab = c.cov_of(a, a), c.cov_of(b, b), c.cov_of(a, b)
            if not (va > 0.0 and vb > 0.0 and math.isfinite(cab)):
                continue
            r = cab / math.sqrt(va * vb)
            if abs(r) > TRADE_CORRELATION:
                out.append((a, b, float(r)))
    return out


def second_lag_verdict(
    c: Candidate, sample_time: float, *, meter_lag_given: bool, bic_gain: float = math.inf
) -> str | None:
    """Why the second lag of a two-lag fit is not supported by the data, or None when it is.

    Conditions 2–4 of the module docstring (BIC's, condition 1, is :func:`choose_order`'s);
    ``bic_gain`` is BIC(one lag) − BIC(two lags), which condition 4 weighs.

    Examples
    --------
    >>> cov = np.diag([1e-4, 1e-4, 1e-6])
    >>> two = Candidate(2, 0.0, 5, ProcessModel(K=1.0, T=2.0, T2=0.01), {"T2": 1e-3},
    ...                 ("K", "T", "T2"), cov)
    >>> second_lag_verdict(two, 0.02, meter_lag_given=True)
    'the second lag 0.01 s is not longer than the sample period 0.02 s'
    """
    m = c.model
    small, name = (m.T2, "T2") if m.T2 <= m.T else (m.T, "T")
    if small <= sample_time:
        return (
            f"the second lag {small:.3g} s is not longer than the sample period {sample_time:g} s"
        )
    se = math.sqrt(c.cov_of(name, name)) if c.cov_of(name, name) >= 0.0 else math.nan
    if not math.isfinite(se):
        return f"the second lag {small:.3g} s has no standard error (not determined)"
    if small - Z95 * se <= 0.0:
        return (
            f"the second lag's 95 % interval {small:.3g} ± {Z95 * se:.2g} s does not exclude zero"
        )
    if not meter_lag_given and not lags_told_apart(c) and bic_gain < BIC_CLOSE:
        return (
            f"with no meter lag given, the two lags {m.T:.3g} s and {m.T2:.3g} s are not "
            f"told apart (|T − T2| within 1.96 standard errors) and BIC prefers them by only "
            f"{bic_gain:.1f} (< {BIC_CLOSE:g})"
        )
    return None


def lags_not_separated(names: tuple[str, ...], cov: FloatArray) -> float | None:
    """corr(T, T2) when it is beyond ±:data:`LAGS_NOT_SEPARATED`, else None.

    Examples
    --------
    >>> lags_not_separated(("T", "T2"), np.array([[1.0, 0.9995], [0.9995, 1.0]]))
    0.9995
    >>> lags_not_separated(("T", "T2"), np.eye(2)) is None
    True
    """
    if "T" not in names or "T2" not in names:
        return None
    i, j = names.index("T"), names.index("T2")
    c = np.asarray(cov, dtype=float)
    denominator = math.sqrt(abs(c[i, i] * c[j, j]))
    if not (math.isfinite(denominator) and denominator > 0.0):
        return None
    corr = float(c[i, j] / denominator)
    return corr if abs(corr) > LAGS_NOT_SEPARATED else None


def lags_told_apart(c: Candidate) -> bool:
    """Whether the two lags of a two-lag fit differ by more than 1.96 standard errors.

    Never when their correlation is beyond ±:data:`LAGS_NOT_SEPARATED`: their separate
    intervals are then withheld, and a difference within them is not one the data determine.
    """
    if lags_not_separated(c.names, c.cov) is not None:
        return False
    var = c.cov_of("T", "T") + c.cov_of("T2", "T2") - 2.0 * c.cov_of("T", "T2")
    se_diff = math.sqrt(var) if var > 0.0 else math.nan
    return math.isfinite(se_diff) and abs(c.model.T - c.model.T2) > Z95 * se_diff


def choose_order(
    candidates: list[Candidate], sample_time: float, *, meter_lag_given: bool
) -> OrderChoice:
    """Keep one order of ``candidates`` by the rule of the module docstring.

    Parameters
    ----------
    candidates : list of Candidate
        One or two fits (orders 1 and 2). A single candidate is kept as given (a fixed order).
    sample_time : float
        h [s].
    meter_lag_given : bool
        Whether the flowmeter lag is a fixed prior (then a second lag need not be told apart
        from the first: the meter's is already in the model).

    Returns
    -------
    OrderChoice
    """
    by_order = {c.order: c for c in candidates}
    if len(by_order) == 1:
        only = candidates[0]
        choice = OrderChoice(only.order, f"order {only.order} was given", tuple(candidates))
    else:
        one, two = by_order[1], by_order[2]
        split = False
        if two.bic >= one.bic:
            reason = f"order 1: BIC prefers it ({one.bic:.1f} against {two.bic:.1f} for two lags)"
            chosen = 1
        else:
            gain = one.bic - two.bic
            objection = second_lag_verdict(
                two, sample_time, meter_lag_given=meter_lag_given, bic_gain=gain
            )
            if objection is None:
                chosen = 2
                merged = lags_not_separated(two.names, two.cov)
                split = merged is not None or (not meter_lag_given and not lags_told_apart(two))
                if merged is not None:
                    # the intervals reported are withheld: the reason must not cite them
                    reason = (
                        f"order 2: BIC prefers it by {gain:.1f} and the second lag is longer "
                        f"than the sample period; the two lags are not told apart "
                        f"(correlation {merged:+.4f}): their split is not determined and "
                        "neither has an interval of its own"
                    )
                else:
                    reason = (
                        f"order 2: BIC prefers it by {gain:.1f}, the second lag is longer than "
                        "the sample period and its 95 % interval excludes zero"
                    )
                    if split:
                        reason += "; the two lags are not told apart: their split is not determined"
            else:
                chosen = 1
                reason = (
                    f"order 1: BIC prefers two lags by {one.bic - two.bic:.1f}, but {objection}"
                )
        choice = OrderChoice(chosen, reason, (one, two))
        choice.split_undetermined = chosen == 2 and split
    choice.trades = _trades(choice.chosen_candidate)
    return choice


__all__ = [
    "BIC_CLOSE",
    "LAGS_NOT_SEPARATED",
    "TRADE_CORRELATION",
    "Candidate",
    "OrderChoice",
    "bic",
    "choose_order",
    "lags_not_separated",
    "lags_told_apart",
    "second_lag_verdict",
]
