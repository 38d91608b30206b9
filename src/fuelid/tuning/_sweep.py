"""One PI over many plant variants: fuel temperature and the identification's uncertainty.

The sweep uses the linear models (exact zero-order hold, the dead time exact in the frequency
response): a thousand variants take a couple of seconds, where the nonlinear plant would take
half a minute (docs/explanation/tuning.md, section 9).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from fuelid.model import model_covariance
from fuelid.plant import PlantConfig, linearise
from fuelid.tuning._cases import DEFAULT_T_RANGE, Anchor
from fuelid.tuning._frequency import robustness
from fuelid.tuning._limits import check_sweep_size
from fuelid.tuning._linearloop import linear_closed_loop
from fuelid.tuning._rules import PISettings

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SweepResult:
    """One PI over many plant variants (temperature and identification uncertainty)."""

    T_fuel: FloatArray
    """Fuel temperature of each variant [K]."""
    K: FloatArray
    T: FloatArray
    delay: FloatArray
    Ms: FloatArray
    gain_margin: FloatArray
    phase_margin_deg: FloatArray
    overshoot_percent: FloatArray
    stable: NDArray[np.bool_]

    def summary(self) -> dict[str, float]:
        """Worst case and 95th percentile of Ms and overshoot, the smallest margins."""
        return {
            "n": self.Ms.size,
            "worst_Ms": float(np.max(self.Ms)),
            "Ms_p95": float(np.percentile(self.Ms, 95)),
            "worst_overshoot_percent": float(np.max(self.overshoot_percent)),
            "overshoot_p95": float(np.percentile(self.overshoot_percent, 95)),
            "min_gain_margin": float(np.min(self.gain_margin)),
            "min_phase_margin_deg": float(np.min(self.phase_margin_deg)),
            "unstable_fraction": float(np.mean(~self.stable)),
        }


def uncertainty_sweep(
    pi: PISettings,
    anchor: Anchor,
    cov_names: Sequence[str],
    cov: FloatArray,
    config: PlantConfig | None,
    *,
    n: int = 1000,
    T_range: tuple[float, float] = DEFAULT_T_RANGE,
    seed: int | None = 0,
) -> SweepResult:
    """Evaluate one PI on ``n`` variants of the identified model.

    Each variant draws a fuel temperature uniformly over ``T_range`` [K] and the estimated
    parameters from N(estimate, cov) (the identification's covariance, its model-parameter block:
    :func:`~fuelid.model.model_covariance`); the physics model then moves K and T from the
    identification's temperature to the drawn one (by ratio, interpolated on a 2 K grid). Draws
    with T ≤ 0 are redrawn; a negative delay is set to 0. Without ``config`` (no plant file of
    the user's says how the loop moves with temperature) every variant stays at the
    identification's temperature: the draws are the covariance's alone. Margins and the step
    overshoot come from the linear models (exact ZOH, exact delay). See
    docs/explanation/tuning.md, section 9.
    """
    check_sweep_size(n)
    rng = np.random.default_rng(seed)
    names, cov = model_covariance(cov_names, cov)
    mean = np.array([getattr(anchor.model, name) for name in names], dtype=float)
    if config is None:
        grid = np.array([anchor.T_fuel, anchor.T_fuel + 1.0])
        k_ratio = t_ratio = np.ones(2)
        temps = np.full(n, anchor.T_fuel)
    else:
        grid = np.arange(T_range[0], T_range[1] + 1e-9, 2.0)
        if grid[-1] < T_range[1]:
            grid = np.append(grid, T_range[1])
        ref = linearise(config, anchor.u, anchor.T_fuel).equivalent_model().model
        phys = [linearise(config, anchor.u, T).equivalent_model().model for T in grid]
        k_ratio = np.array([m.K / ref.K for m in phys])
        t_ratio = np.array([m.T / ref.T for m in phys])
        temps = rng.uniform(T_range[0], T_range[1], n)
    draws = np.empty((n, len(names)))
    filled = 0
    t_index = names.index("T") if "T" in names else None
    while filled < n:
        batch = rng.multivariate_normal(mean, cov, size=n - filled) if names else np.empty((n, 0))
        if t_index is not None:
            batch = batch[batch[:, t_index] > 0.0]
        draws[filled : filled + batch.shape[0]] = batch
        filled += batch.shape[0]
    out: dict[str, list[float]] = {key: [] for key in ("K", "T", "delay", "Ms", "gm", "pm", "os")}
    stable = np.empty(n, dtype=bool)
    for i in range(n):
        params = dict(zip(names, draws[i], strict=True))
        params["delay"] = max(params.get("delay", anchor.model.delay), 0.0)
        for name in ("T2", "T_f"):
            if name in params:
                params[name] = max(params[name], 0.0)
        base = replace(anchor.model, **params)
        model = replace(
            base,
            K=base.K * float(np.interp(temps[i], grid, k_ratio)),
            T=base.T * float(np.interp(temps[i], grid, t_ratio)),
        )
        r = robustness(model, pi, n=600)
        step = linear_closed_loop(model, pi)
        out["K"].append(model.K)
        out["T"].append(model.T)
        out["delay"].append(model.delay)
        out["Ms"].append(r.Ms)
        out["gm"].append(r.gain_margin)
        out["pm"].append(r.phase_margin_deg)
        out["os"].append(step.setpoint.overshoot_percent if r.stable else math.inf)
        stable[i] = r.stable
    return SweepResult(
        T_fuel=temps,
        K=np.array(out["K"]),
        T=np.array(out["T"]),
        delay=np.array(out["delay"]),
        Ms=np.array(out["Ms"]),
        gain_margin=np.array(out["gm"]),
        phase_margin_deg=np.array(out["pm"]),
        overshoot_percent=np.array(out["os"]),
        stable=stable,
    )
