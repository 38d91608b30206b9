"""Acceptance bands of the Monte Carlo tests, derived from the statistics before a test runs.

Every band holds, when what the test checks is true, with probability 1 − :data:`FALSE_ALARM`
(0.1 % per check): a test outside its band is news about the code, not bad luck.
"""

from __future__ import annotations

import math

FALSE_ALARM = 1e-3
"""Chance that a check whose statistics hold fails anyway, per check (pre-registered)."""


def coverage_band(n: int, p_miss: float = 0.05, alarm: float = FALSE_ALARM) -> tuple[int, int]:
    """Misses of n correct 95 % intervals: the two-sided band holding with probability 1 − alarm.

    The smallest lo and largest hi with P(X < lo) ≤ alarm/2 and P(X > hi) ≤ alarm/2 for
    X ~ Binomial(n, p_miss): too many misses are intervals too narrow, too few too wide.

    Examples
    --------
    >>> coverage_band(10), coverage_band(100)
    ((0, 4), (0, 13))
    >>> coverage_band(500)
    (11, 42)
    """
    pmf = [math.comb(n, m) * p_miss**m * (1.0 - p_miss) ** (n - m) for m in range(n + 1)]
    lo, below = 0, 0.0
    while lo < n and below + pmf[lo] <= alarm / 2:
        below += pmf[lo]
        lo += 1
    hi, above = n, 0.0
    while hi > 0 and above + pmf[hi] <= alarm / 2:
        above += pmf[hi]
        hi -= 1
    return lo, hi


def z_bound(m: int, alarm: float = FALSE_ALARM) -> float:
    """|z| bound of m standard normal values, all within it with probability 1 − alarm.

    Šidák: each within ±b with probability (1 − alarm)^(1/m).

    Examples
    --------
    >>> round(z_bound(1), 2), round(z_bound(10), 2)
    (3.29, 3.89)
    """
    from statistics import NormalDist

    each = (1.0 - alarm) ** (1.0 / max(m, 1))
    return NormalDist().inv_cdf(0.5 + each / 2.0)


def rmse_ratio_band(runs: int, alarm: float = FALSE_ALARM) -> tuple[float, float]:
    """RMSE over the Cramér–Rao bound of an efficient, unbiased estimator in ``runs`` runs.

    With Gaussian errors of variance CRB, runs·RMSE²/CRB ~ χ²(runs): the ratio lies within
    [√(χ²_{α/2}/runs), √(χ²_{1−α/2}/runs)] with probability 1 − alarm (relative spread about
    1/√(2·runs)).

    Examples
    --------
    >>> [round(v, 3) for v in rmse_ratio_band(150)]
    [0.814, 1.193]
    """
    from scipy.stats import chi2

    low, high = chi2.ppf([alarm / 2.0, 1.0 - alarm / 2.0], runs)
    return math.sqrt(low / runs), math.sqrt(high / runs)


def most_failures(n: int, p_fail: float, alarm: float = FALSE_ALARM) -> int:
    """Largest count of failures in n trials that a failure rate of ``p_fail`` still explains.

    The smallest c with P(X > c) ≤ alarm for X ~ Binomial(n, p_fail): with the true rate at
    most p_fail, more than c failures happen with probability at most ``alarm``.

    Examples
    --------
    >>> most_failures(12, 0.01), most_failures(100, 0.01)
    (2, 5)
    """
    above, c = 1.0, -1
    while above > alarm:
        c += 1
        above -= math.comb(n, c) * p_fail**c * (1.0 - p_fail) ** (n - c)
    return c


def most_failures_under(n: int, rate: float = 0.01, confidence: float = 0.95) -> int:
    """Largest failure count in n trials whose one-sided upper bound stays under ``rate``.

    The Clopper–Pearson upper bound of a binomial rate with c failures of n at ``confidence``
    is the quantile ``confidence`` of Beta(c + 1, n − c); −1 when even no failure in n trials
    bounds the rate under ``rate`` (n too small: n must be at least 299 for 1 % at 95 %).

    Examples
    --------
    >>> most_failures_under(300), most_failures_under(100), most_failures_under(1000)
    (0, -1, 4)
    """
    from scipy.stats import beta

    c = -1
    while c + 1 < n and float(beta.ppf(confidence, c + 2, n - c - 1)) < rate:
        c += 1
    return c
