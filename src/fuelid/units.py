"""Unit constants and the few conversions at fuelid's edges.

Inside fuelid every quantity is SI (m³/s, Pa, K, s); engineering units (L/min, MPa, °C) appear
only where files, the command line and JSON meet the user, and they are converted with these.

Examples
--------
>>> celsius_to_kelvin(20.0), round(kelvin_to_celsius(253.15), 2)
(293.15, -20.0)
>>> LPM_PER_M3S * 0.001
60.0
"""

from __future__ import annotations

T0: float = 273.15
"""0 °C in kelvin [K]; a Celsius temperature t is T = t + T0."""

LPM_PER_M3S: float = 60_000.0
"""L/min in one m³/s."""

PA_PER_MPA: float = 1e6
"""Pa in one MPa."""

M_PER_MM: float = 1e-3
"""m in one mm."""


def celsius_to_kelvin(t_degC: float) -> float:
    """Temperature in K from °C."""
    return t_degC + T0


def kelvin_to_celsius(T: float) -> float:
    """Temperature in °C from K."""
    return T - T0
