"""Unit constants and the few conversions at fuelid's edges.

Inside fuelid every quantity is SI (m³/s, Pa, Pa·s, m, W, rad/s, K, s); engineering units (L/min,
MPa, mPa·s, mm, cm³, kW, rpm, °C) appear only where files, the command line and JSON meet the
user, and they are converted with these, in one place per edge. A constant ``A_PER_B`` is the
number of A in one B: a value in B times it is the value in A, and a value in A divided by it is
the value in B.

Examples
--------
Each conversion pair, there and back:

>>> celsius_to_kelvin(20.0), round(kelvin_to_celsius(253.15), 2)  # °C ↔ K
(293.15, -20.0)
>>> 1e-3 * LPM_PER_M3S, 60.0 / LPM_PER_M3S  # m³/s ↔ L/min
(60.0, 0.001)
>>> 1.2 * PA_PER_MPA, 1.5e6 / PA_PER_MPA  # MPa ↔ Pa
(1200000.0, 1.5)
>>> 32.0 * M_PER_MM, 0.045 / M_PER_MM  # mm ↔ m
(0.032, 45.0)
>>> round(50.0 * M3_PER_CM3, 15), round(5e-5 / M3_PER_CM3, 9)  # cm³ ↔ m³
(5e-05, 50.0)
>>> 1.5 * PA_S_PER_MPA_S, 2e-3 / PA_S_PER_MPA_S  # mPa·s ↔ Pa·s
(0.0015, 2.0)
>>> 7.5 * W_PER_KW, 7500.0 / W_PER_KW  # kW ↔ W
(7500.0, 7.5)
>>> round(1500.0 * RAD_S_PER_RPM, 6), round(157.079633 / RAD_S_PER_RPM, 4)  # rpm ↔ rad/s
(157.079633, 1500.0)
>>> 0.5 * TWO_PI == math.pi, math.pi / TWO_PI  # revolutions ↔ rad: half a turn is π rad
(True, 0.5)
>>> kelvin_to_celsius(celsius_to_kelvin(DEFAULT_FUEL_TEMPERATURE_C)) == DEFAULT_FUEL_TEMPERATURE_C
True
>>> FUEL_TEMPERATURE_RANGE_C[0] < DEFAULT_FUEL_TEMPERATURE_C < FUEL_TEMPERATURE_RANGE_C[1]
True
"""

from __future__ import annotations

import math

__all__ = [
    "DEFAULT_FUEL_TEMPERATURE_C",
    "FUEL_TEMPERATURE_RANGE_C",
    "LPM_PER_M3S",
    "M3_PER_CM3",
    "M_PER_MM",
    "PA_PER_MPA",
    "PA_S_PER_MPA_S",
    "RAD_S_PER_RPM",
    "T0",
    "TWO_PI",
    "W_PER_KW",
    "celsius_to_kelvin",
    "format_celsius",
    "kelvin_to_celsius",
]

T0: float = 273.15
"""0 °C in kelvin [K]; a Celsius temperature t is T = t + T0."""

DEFAULT_FUEL_TEMPERATURE_C: float = 20.0
"""The fuel temperature [°C] fuelid takes when nothing gives one (a log without a fuel
temperature column, no ``--fuel-temp``): every output that rests on it says it was assumed. The
one home of this default (here, where the command line's help can read it without numpy);
:data:`fuelid.workflow.T_REF` is the same in kelvin."""

FUEL_TEMPERATURE_RANGE_C: tuple[float, float] = (-60.0, 150.0)
"""Plausible fuel temperatures [°C]; outside is another unit (K, °F) or a broken sensor: a log's
fuel-temperature column and ``fuelid identify --fuel-temp`` are refused outside it."""

LPM_PER_M3S: float = 60_000.0
"""L/min in one m³/s: q_Lpm = q·LPM_PER_M3S, q = q_Lpm/LPM_PER_M3S."""

PA_PER_MPA: float = 1e6
"""Pa in one MPa: p = p_MPa·PA_PER_MPA, p_MPa = p/PA_PER_MPA."""

M_PER_MM: float = 1e-3
"""m in one mm: d = d_mm·M_PER_MM, d_mm = d/M_PER_MM."""

M3_PER_CM3: float = 1e-6
"""m³ in one cm³ (a pump's displacement per revolution): D = D_cm3·M3_PER_CM3."""

PA_S_PER_MPA_S: float = 1e-3
"""Pa·s in one mPa·s (dynamic viscosity; 1 mPa·s = 1 cP): μ = μ_mPa_s·PA_S_PER_MPA_S."""

W_PER_KW: float = 1e3
"""W in one kW: P = P_kW·W_PER_KW."""

TWO_PI: float = 2.0 * math.pi
"""2π: radians in one revolution (or one electrical cycle) [rad/rev].

A flow per revolution times ω/TWO_PI is a flow per second; a frequency f [Hz] is the angular
speed TWO_PI·f [rad/s].
"""

RAD_S_PER_RPM: float = TWO_PI / 60.0
"""rad/s in one rpm (one revolution per 60 s): ω = n_rpm·RAD_S_PER_RPM, n_rpm = ω/RAD_S_PER_RPM."""


def celsius_to_kelvin(t_degC: float) -> float:
    """Temperature in K from °C.

    >>> celsius_to_kelvin(0.0), celsius_to_kelvin(20.0)
    (273.15, 293.15)
    """
    return t_degC + T0


def kelvin_to_celsius(T: float) -> float:
    """Temperature in °C from K.

    >>> kelvin_to_celsius(273.15), round(kelvin_to_celsius(celsius_to_kelvin(-20.0)), 12)
    (0.0, -20.0)
    """
    return T - T0


def format_celsius(T: float) -> str:
    """A fuel temperature given in K, as text in °C to 0.1 °C.

    A fuel-temperature sensor resolves about 0.1 °C, so a log's mean temperature has no more
    digits worth reading. Trailing zeros are dropped: a whole degree reads as one (``20``, not
    ``20.0``).

    >>> format_celsius(celsius_to_kelvin(12.9985)), format_celsius(celsius_to_kelvin(-20.0))
    ('13', '-20')
    >>> format_celsius(celsius_to_kelvin(12.94)), format_celsius(celsius_to_kelvin(-0.04))
    ('12.9', '0')
    """
    return f"{round(kelvin_to_celsius(T), 1) + 0.0:.1f}".removesuffix(".0")
