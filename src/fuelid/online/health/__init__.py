"""Loop health of one window of PLC samples: what a performance monitor reports per window.

Pure functions on numpy arrays of one window, sample by sample: the time ``t`` [s], the command
``u`` [V], the flow ``y`` [L/min], the setpoint [L/min], the controller's ``mode`` (0 MAN, 1 AUTO)
and the ``ok`` quality mask (True where the recorder found the sample good). The control error is
e = setpoint − y [L/min].

- :func:`time_in_auto`, :func:`time_at_limits`: the share of the window the loop was in AUTO and
  the share the output sat at one of its limits (the service's gates and freeze conditions);
- :func:`hagglund_oscillation`: Hägglund's oscillation detector (load disturbances recognised by
  the IAE between zero crossings of e, counted with exponential forgetting);
- :func:`setpoint_responses`: IAE, overshoot, settling and rise time of every setpoint step made
  in AUTO;
- :func:`harris_index`: the minimum-variance (Harris) performance index of a regulatory stretch;
- :func:`sensor_health`: noise level, exactly repeated values (a stuck transmitter) and the
  quantisation step of the flow reading;
- :func:`loop_health`: all of the above for one window, in one :class:`LoopHealth` with a
  JSON-ready :meth:`~LoopHealth.to_json`.

Each metric family is a private module of its own (``_shares.py``, ``_oscillation.py``,
``_setpoint.py``, ``_harris.py``, ``_sensor.py``, ``_loop.py``); import the names from here.

References
----------
T. Hägglund, "A control-loop performance monitor", Control Engineering Practice 3(11) (1995)
1543–1551. L. Desborough, T. Harris, "Performance assessment measures for univariate feedback
control", Can. J. Chem. Eng. 70 (1992) 1186–1197. B. Huang, S. L. Shah, *Performance Assessment
of Control Loops* (Springer, 1999), ch. 2–3. K. J. Åström, T. Hägglund, *Advanced PID Control*
(ISA, 2006), §7.2 (step-response measures). P. J. Rousseeuw, C. Croux, "Alternatives to the
median absolute deviation", J. Am. Stat. Assoc. 88 (1993) 1273–1283 (robust scale).
"""

from __future__ import annotations

from fuelid.online._moves import RAMP_GAP_S
from fuelid.online.health._harris import (
    MAX_AR_ORDER,
    SAMPLES_PER_AR_ORDER,
    HarrisIndex,
    harris_index,
)
from fuelid.online.health._loop import LoopHealth, loop_health
from fuelid.online.health._oscillation import (
    OSCILLATION_AMPLITUDE_FRACTION,
    OSCILLATION_COUNT_LIMIT,
    SUPERVISION_PERIODS,
    Oscillation,
    hagglund_oscillation,
    half_period_iae,
)
from fuelid.online.health._sensor import SensorHealth, noise_level, quantisation_step, sensor_health
from fuelid.online.health._setpoint import (
    MIN_STEP_LPM,
    SETTLING_FRACTION,
    SETTLING_NOISE_LEVELS,
    SetpointResponse,
    setpoint_responses,
    step_response_measures,
)
from fuelid.online.health._shares import (
    AUTO,
    LIMIT_TOLERANCE_V,
    U_LIMITS_V,
    time_at_limits,
    time_in_auto,
)

__all__ = [
    "AUTO",
    "LIMIT_TOLERANCE_V",
    "MAX_AR_ORDER",
    "MIN_STEP_LPM",
    "OSCILLATION_AMPLITUDE_FRACTION",
    "OSCILLATION_COUNT_LIMIT",
    "RAMP_GAP_S",
    "SAMPLES_PER_AR_ORDER",
    "SETTLING_FRACTION",
    "SETTLING_NOISE_LEVELS",
    "SUPERVISION_PERIODS",
    "U_LIMITS_V",
    "HarrisIndex",
    "LoopHealth",
    "Oscillation",
    "SensorHealth",
    "SetpointResponse",
    "hagglund_oscillation",
    "half_period_iae",
    "harris_index",
    "loop_health",
    "noise_level",
    "quantisation_step",
    "sensor_health",
    "setpoint_responses",
    "step_response_measures",
    "time_at_limits",
    "time_in_auto",
]
