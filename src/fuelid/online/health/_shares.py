"""The shares of a window: time in AUTO, time with the command at an output limit."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from fuelid.online.health._arrays import _ok_mask

AUTO = 1
"""The controller mode value of AUTO (0 is MAN)."""
U_LIMITS_V = (1.0, 5.0)
"""The drive's command range [V]: the PI's output limits."""
LIMIT_TOLERANCE_V = 0.005
"""A command within this of a limit counts as at the limit [V] (about 14 counts of a 0–10 V,
27648-count analog output)."""


def time_in_auto(mode: ArrayLike, ok: ArrayLike | None = None) -> float:
    """Share of the good samples in which the controller is in AUTO.

    Parameters
    ----------
    mode : array
        Controller mode per sample (1 AUTO, 0 MAN) [-].
    ok : array of bool, optional
        Quality mask; None: every sample counts.

    Returns
    -------
    float
        Share in [0, 1] [-]; nan without good samples.

    Notes
    -----
    The "time in normal mode" of control-loop performance monitors (Jelali, *Control
    Performance Management in Industrial Automation*, Springer 2013, §2.4): a loop that spends
    its time in MAN is not being assessed, whatever its other numbers say.

    Examples
    --------
    >>> time_in_auto([1, 1, 0, 1], ok=[True, True, True, False])
    0.6666666666666666
    """
    m = np.asarray(mode, dtype=float)
    good = _ok_mask(m.size, ok) & np.isfinite(m)
    if not good.any():
        return math.nan
    return float(np.mean(m[good] == AUTO))


def time_at_limits(
    u: ArrayLike,
    u_min: float = U_LIMITS_V[0],
    u_max: float = U_LIMITS_V[1],
    tol: float = LIMIT_TOLERANCE_V,
    ok: ArrayLike | None = None,
) -> float:
    """Share of the good samples with the command at (within ``tol`` of) an output limit.

    Parameters
    ----------
    u : array
        Command [V].
    u_min, u_max : float
        Output limits [V].
    tol : float
        Distance from a limit that still counts as at it [V].
    ok : array of bool, optional
        Quality mask; None: every sample counts.

    Returns
    -------
    float
        Share in [0, 1] [-]; nan without good samples.

    Notes
    -----
    A saturated output opens the loop: no control-performance measure means anything over such
    a stretch, and an identification window dominated by it carries no closed-loop information
    (Jelali 2013, §2.4; Huang & Shah 1999, §2.4 assume an unsaturated linear loop).

    Examples
    --------
    >>> time_at_limits([1.0, 1.002, 3.0, 5.0])
    0.75
    """
    v = np.asarray(u, dtype=float)
    good = _ok_mask(v.size, ok) & np.isfinite(v)
    if not good.any():
        return math.nan
    x = v[good]
    return float(np.mean((x <= u_min + tol) | (x >= u_max - tol)))


__all__ = ["AUTO", "LIMIT_TOLERANCE_V", "U_LIMITS_V", "time_at_limits", "time_in_auto"]
