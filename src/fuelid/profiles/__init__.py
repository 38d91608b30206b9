"""What drives a run over time: the simulator's input profiles and the virtual PLC's run profiles.

- :class:`InputProfile` and the functions that make one: the controller output as the PLC holds
  it (piecewise constant), the input of :func:`fuelid.plant.simulate.simulate` and of the closed
  loop;
- :mod:`~fuelid.profiles.runs`: what the virtual PLC's operator does over time (setpoint,
  manual command and fuel-temperature breakpoint tables, linearly interpolated), read from CSV.

Both sit on the errors layer only (numpy, no pandas): the plant and the PLC read them, they
read neither.

The public API
--------------
``fuelid.profiles`` exports the input-profile names, as the module of that name did before
0.2.0: :class:`InputProfile`, :func:`step_profile`, :func:`step_sequence`,
:func:`random_levels`, :func:`held_profile`. The run profiles are promised at
``fuelid.profiles.runs``: :class:`~fuelid.profiles.runs.Profile`,
:func:`~fuelid.profiles.runs.load_profile`, :func:`~fuelid.profiles.runs.run_profile`,
:func:`~fuelid.profiles.runs.steps_profile`, :func:`~fuelid.profiles.runs.demo_run_profile`,
:func:`~fuelid.profiles.runs.demo_temperature` (their old path, ``fuelid.plc.virtual.profiles``,
was removed in 0.3.0).
"""

from __future__ import annotations

from fuelid.profiles._inputs import (
    InputProfile,
    held_profile,
    random_levels,
    step_profile,
    step_sequence,
)

__all__ = [
    "InputProfile",
    "held_profile",
    "random_levels",
    "step_profile",
    "step_sequence",
]
