"""The ``units`` map of a model file: read, converted to fuelid's units, or refused.

A model file (``fuelid identify --json``, ``fuelid plant info --json``) says the unit of its
numbers in its ``units`` map. :func:`in_default_units` reads the entries of the numbers the
model file reader takes (:mod:`fuelid.io.fitted_model`): the model's K, T, T2, T_f and delay
(and with them their ``stderr``, ``ci95`` and covariance entries), the operating point's ``u``
and ``fuel_temperature`` (and the command bands' ``u_low``, ``u_high``, ``K``). A unit fuelid
writes is taken as it is; a known alternative (ms or min for s, L/s, L/h or m³/h for L/min,
mV for V, K for °C) is converted; any other unit is refused with the key and the unit found,
never passed over. Entries of numbers the reader does not take (``fit_percent``, ``flow``,
...) are not looked at. docs/reference/model-file.md lists the units.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any

from fuelid.errors import DataError
from fuelid.units import T0

SECONDS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "min": 60.0}
"""Time units [s per unit] read for T, T2, T_f and delay."""
FLOWS = {"L/min": 1.0, "l/min": 1.0, "L/s": 60.0, "L/h": 1.0 / 60.0, "m³/h": 1000.0 / 60.0}
"""Flow units [L/min per unit] read in the numerator of K."""
VOLTS = {"V": 1.0, "mV": 1e-3}
"""Command units [V per unit] read for u and in the denominator of K."""
CELSIUS = {"degC": 0.0, "°C": 0.0, "C": 0.0, "K": -T0}
"""Temperature units, as the offset [°C] added to a value in them."""
GAIN_AS_WRITTEN = ("output unit per input unit", "(L/min)/V")
"""How fuelid writes K's unit (identify: "output unit per input unit (...)"; plant info)."""
TIME_KEYS = ("T", "T2", "T_f", "delay")


def _gain_factor(unit: str) -> float | None:
    """(L/min)/V per unit of K, or None when the unit is not one fuelid reads."""
    if unit.startswith(GAIN_AS_WRITTEN):
        return 1.0
    found = re.fullmatch(r"\(?\s*([^()]+?)\s*\)?\s*/\s*(m?V)", unit.replace("m3/h", "m³/h"))
    if found is None or found.group(1) not in FLOWS:
        return None
    return FLOWS[found.group(1)] / VOLTS[found.group(2)]


def _factors(units: dict[str, Any], file: Path) -> dict[str, tuple[float, float]]:
    """(scale, offset) per key whose unit differs from fuelid's, refusing unknown units."""
    found: dict[str, tuple[float, float]] = {}
    for key, value in units.items():
        if key not in (*TIME_KEYS, "K", "u", "fuel_temperature"):
            continue
        unit = str(value).strip()
        if key in TIME_KEYS:
            scale: float | None = SECONDS.get(unit)
            offset = 0.0
            known = "s, ms or min"
        elif key == "K":
            scale, offset = _gain_factor(unit), 0.0
            known = "(L/min)/V, or L/s, L/h or m³/h per V or mV"
        elif key == "u":
            scale, offset = VOLTS.get(unit), 0.0
            known = "V or mV"
        else:
            scale, offset = (1.0, CELSIUS[unit]) if unit in CELSIUS else (None, 0.0)
            known = "degC (°C) or K"
        if scale is None:
            raise DataError(
                f"model file {str(file)!r}: units.{key} is {unit!r}: fuelid reads {key} in {known}"
            )
        if (scale, offset) != (1.0, 0.0):
            found[key] = (scale, offset)
    return found


def _scaled(value: Any, scale: float, offset: float = 0.0) -> Any:
    """A number converted; anything else as it is (the reader refuses or skips it later)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return value
    return value * scale + offset


def in_default_units(data: dict[str, Any], file: Path) -> dict[str, Any]:
    """The model file's JSON with every number the reader takes in fuelid's units.

    Raises
    ------
    DataError
        When ``units`` is not an object, or names a unit fuelid does not read for one of the
        keys it reads (the message names the key and the unit found).

    Examples
    --------
    >>> data = {"model": {"K": 0.25, "T": 1500.0}, "units": {"K": "(L/s)/V", "T": "ms"}}
    >>> in_default_units(data, Path("m.json"))["model"]
    {'K': 15.0, 'T': 1.5}
    >>> in_default_units({"model": {"T": 1.0}, "units": {"T": "h"}}, Path("m.json"))
    Traceback (most recent call last):
    ...
    fuelid.errors.DataError: model file 'm.json': units.T is 'h': fuelid reads T in s, ms or min
    """
    units = data.get("units")
    if units is None:
        return data
    if not isinstance(units, dict):
        raise DataError(f"model file {str(file)!r}: 'units' is not an object")
    factors = _factors(units, file)
    if not factors:
        return data
    out = copy.deepcopy(data)
    model_factors = {k: f[0] for k, f in factors.items() if k in ("K", *TIME_KEYS)}
    for block in ("model", "stderr"):
        entries = out.get(block)
        if isinstance(entries, dict):
            for key, scale in model_factors.items():
                entries[key] = _scaled(entries.get(key), scale)
    intervals = out.get("ci95")
    if isinstance(intervals, dict):
        for key, scale in model_factors.items():
            bounds = intervals.get(key)
            if isinstance(bounds, list):
                intervals[key] = [_scaled(b, scale) for b in bounds]
    _scale_covariance(out.get("cov"), model_factors)
    for key in ("u", "fuel_temperature"):
        if key in factors:
            scale, offset = factors[key]
            for holder in (out, out.get("operating_point")):
                if isinstance(holder, dict) and key in holder:
                    holder[key] = _scaled(holder[key], scale, offset)
    _scale_bands(out.get("diagnostics"), factors)
    return out


def _scale_covariance(block: Any, factors: dict[str, float]) -> None:
    """Each covariance entry times the factors of its row's and its column's parameter."""
    if not (isinstance(block, dict) and isinstance(block.get("names"), list)):
        return
    matrix = block.get("matrix")
    if not isinstance(matrix, list):
        return
    scales = [factors.get(str(name), 1.0) for name in block["names"]]
    for i, row in enumerate(matrix):
        if isinstance(row, list) and len(row) == len(scales) and i < len(scales):
            matrix[i] = [_scaled(v, scales[i] * scales[j]) for j, v in enumerate(row)]


def _scale_bands(diagnostics: Any, factors: dict[str, tuple[float, float]]) -> None:
    """The command bands' edges in V and their K (and its error) in (L/min)/V."""
    nonlinearity = diagnostics.get("nonlinearity") if isinstance(diagnostics, dict) else None
    rows = nonlinearity.get("bands") if isinstance(nonlinearity, dict) else None
    u_scale = factors.get("u", (1.0, 0.0))[0]
    K_scale = factors.get("K", (1.0, 0.0))[0]
    for row in rows if isinstance(rows, list) else []:
        if isinstance(row, dict):
            for key, scale in (("u_low", u_scale), ("u_high", u_scale), ("K", K_scale)):
                row[key] = _scaled(row.get(key), scale)
            row["stderr"] = _scaled(row.get("stderr"), K_scale)
