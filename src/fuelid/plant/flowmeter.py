"""Turbine flowmeter: a first-order lag plus a pure delay, with noise and a resolution.

The lag is the rotor's inertia and the meter's filtering; the delay τ is the meter's gate or
processing time plus the PLC's scan and sampling. It is not a transport delay: in an
incompressible line a flow change travels at the speed of sound (about 0.1 s per 100 m).
The turbine's lag shrinks as the flow grows (roughly T_f ∝ 1/q), so a fixed T_f is right near
the operating point it was calibrated at.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import Field

from fuelid.plant._section import Section


class FlowmeterConfig(Section):
    """Flowmeter as the PLC sees it (TOML section ``[flowmeter]``)."""

    time_constant_s: float = Field(ge=0.0, le=60.0, description="first-order lag T_f [s]")
    delay_s: float = Field(ge=0.0, le=60.0, description="pure delay τ, meter plus PLC [s]")
    span_Lpm: float = Field(gt=0.0, description="full-scale flow of the meter's output [L/min]")
    noise_std_Lpm: float = Field(
        0.0, ge=0.0, description="standard deviation of white measurement noise [L/min]"
    )
    resolution_Lpm: float = Field(
        0.0, ge=0.0, description="quantisation step of the value the PLC reads (0: none) [L/min]"
    )


def measure_flow(
    q_lagged: ArrayLike,
    noise_std: float = 0.0,
    resolution: float = 0.0,
    rng: np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """What the PLC reads: the lagged, delayed flow plus white noise, then quantised.

    Parameters
    ----------
    q_lagged : array
        Flow after the meter's lag and delay [any flow unit].
    noise_std : float
        Standard deviation of additive white Gaussian noise [same unit].
    resolution : float
        Quantisation step [same unit]; 0 for none. Quantisation comes after the noise, as in a
        real A/D chain.
    rng : numpy.random.Generator, optional
        Source of the noise (seed it for reproducible logs).

    Returns
    -------
    ndarray
        Measured flow [same unit].

    Examples
    --------
    >>> measure_flow([10.04, 10.06, 20.0], resolution=0.1).tolist()
    [10.0, 10.100000000000001, 20.0]
    """
    y = np.array(q_lagged, dtype=float)
    if noise_std > 0.0:
        generator = rng if rng is not None else np.random.default_rng()
        y = y + generator.normal(0.0, noise_std, size=y.shape)
    if resolution > 0.0:
        y = np.round(y / resolution) * resolution
    return y
