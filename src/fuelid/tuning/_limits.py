"""Limits of what fuelid tunes, and the guards that refuse anything beyond them.

A model or option outside these limits can only come from a unit mix-up (ms for s, mL for L) or a
failed identification; tuning it would take minutes or overflow, and the gains would mean
nothing. The guards run before any work is done and raise :class:`~fuelid.errors.FuelidError`
with the reason (exit code 2 at the command line). The limits are documented in the command
reference (docs/reference/cli.md, ``fuelid tune``) and in docs/explanation/tuning.md section 10.
"""

from __future__ import annotations

from fuelid.errors import FuelidError
from fuelid.lti import check_control_period
from fuelid.model import ProcessModel

MAX_TIME_SCALE = 1e5
"""Longest time constant or delay [s] of a model fuelid tunes (about a day)."""
MIN_TIME_CONSTANT = 1e-6
"""Shortest non-zero time constant [s]."""
GAIN_RANGE = (1e-6, 1e6)
"""Process gains [output unit per input unit] fuelid tunes."""
MAX_PERIODS = (1000, 10_000)
"""Largest delay and largest sum of time constants, in control periods, of a sampled loop."""
MAX_SWEEP = 20_000
"""Most plant variants of an uncertainty sweep (about 30 s on two cores)."""
MAX_BANDS = 50
"""Most temperature bands of a schedule or a temperature check (each band is a tuning)."""
MAX_FLOW_BANDS = 10
"""Most flow (command) bands per temperature band of a schedule."""


def check_sweep_size(n: int) -> None:
    """Refuse an uncertainty sweep of fewer than 1 or more than :data:`MAX_SWEEP` variants."""
    if not 1 <= n <= MAX_SWEEP:
        raise FuelidError(f"a sweep takes 1 to {MAX_SWEEP:,} plant variants, got {n}")


def check_tunable(model: ProcessModel, control_period: float) -> None:
    """Refuse a model or control period far outside any flow loop, before any work is done.

    Raises
    ------
    FuelidError
        With the reason, e.g. a delay of more than 1,000 control periods.

    Examples
    --------
    >>> check_tunable(ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2), 1.0)
    >>> check_tunable(ProcessModel(K=13.5, T=1260.0, delay=0.2), 0.01)
    Traceback (most recent call last):
    ...
    fuelid.errors.FuelidError: time constants of 1260 s span more than 10000 control periods of \
0.01 s: check the units or --control-period
    """
    check_control_period(control_period)
    lo, hi = GAIN_RANGE
    if model.K > 0.0 and not lo <= model.K <= hi:
        raise FuelidError(f"process gain K = {model.K:g} is outside {lo:g}…{hi:g}: check its units")
    for name in ("T", "T2", "T_f", "delay"):
        value = getattr(model, name)
        if value > MAX_TIME_SCALE:
            raise FuelidError(
                f"model {name} = {value:g} s exceeds {MAX_TIME_SCALE:g} s: check its units"
            )
        if name != "delay" and 0.0 < value < MIN_TIME_CONSTANT:
            raise FuelidError(
                f"model {name} = {value:g} s is below {MIN_TIME_CONSTANT:g} s: give 0 for no lag"
            )
    if control_period > 0.0:
        max_delay, max_lags = MAX_PERIODS
        if model.delay > max_delay * control_period:
            raise FuelidError(
                f"delay {model.delay:g} s is more than {max_delay} control periods of "
                f"{control_period:g} s: check the units or --control-period"
            )
        if sum(model.time_constants) > max_lags * control_period:
            raise FuelidError(
                f"time constants of {sum(model.time_constants):g} s span more than {max_lags} "
                f"control periods of {control_period:g} s: check the units or --control-period"
            )
