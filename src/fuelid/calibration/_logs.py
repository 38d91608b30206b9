"""The logs ``fuelid calibrate`` fits: read as ``fuelid identify`` reads them, gaps bridged or cut.

A calibration simulates each log on the plant ODE from rest at its first command. A short gap (a
few bad cells of a historian export, at most :data:`BRIDGE_MAX_PERIODS` sample periods) is
simulated through: the PLC held the command, so the record keeps the sample before the gap's
command until the sample after it, and the missing flow samples are simply not fitted (nothing is
invented). A longer gap ends the usable log: the command during it is unknown and the stretch after
it does not start at rest, so only the stretch before it is calibrated, and a note says how much
of the log that is (samples, seconds and share).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fuelid.calibration.plant_model import FUEL_TEMPERATURE_KEY
from fuelid.errors import DataError
from fuelid.greybox import Record
from fuelid.io import FILL_GAPS_MAX_PERIODS
from fuelid.io.logs import load_log
from fuelid.io.timeseries import (
    FUEL_TEMPERATURE_COLUMN,
    INPUT_COLUMN,
    OUTPUT_COLUMN,
    TIME_COLUMN,
    IOData,
)
from fuelid.units import T0 as KELVIN

TEMPERATURE_SPREAD_K = 1.0
"""A log whose fuel temperature spans more than this is calibrated at its mean, with a warning."""
BRIDGE_MAX_PERIODS = FILL_GAPS_MAX_PERIODS
"""Gaps up to this many sample periods are simulated through with the command held; a longer
one ends the usable log (the same bound as ``--fill-gaps``, for the same reason: a command step
inside the gap is seen at its end, shifting it by up to the gap)."""
_JOINT_SEGMENTS = ", identified jointly (each with its own initial state)"
"""What the log reader says identification does with segments; calibration does otherwise."""


@dataclass(frozen=True)
class CalibrationLog:
    """One log, loaded: its record (flow, and pressure when logged) and where it came from."""

    path: Path
    sha256: str
    record: Record
    fuel_temperature_C: float
    notes: tuple[str, ...] = ()


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def load_calibration_log(
    path: str | Path,
    *,
    fuel_temp_C: float | None = None,
    time_col: str | None = TIME_COLUMN,
    input_col: str = INPUT_COLUMN,
    output_col: str = OUTPUT_COLUMN,
    pressure_col: str | None = None,
    sample_time: float | None = None,
    bad_values: Sequence[str] = (),
    input_scale: Sequence[float] | None = None,
    output_scale: Sequence[float] | None = None,
    fuel_temperature_col: str | None = FUEL_TEMPERATURE_COLUMN,
    max_gap: float | None = None,
    flow_unit: str | None = None,
) -> CalibrationLog:
    """Read a log for calibration.

    Parameters
    ----------
    path : str or Path
        CSV or Parquet log, as ``fuelid identify`` reads it.
    fuel_temp_C : float, optional
        The log's fuel temperature [°C]; default the mean of its fuel-temperature column.
    time_col, input_col, output_col, sample_time, input_scale, output_scale, max_gap
        As for :func:`~fuelid.io.logs.load_log`; after scaling the output is the flow
        [L/min], the input the command [V].
    pressure_col : str, optional
        Column of the pump outlet pressure [MPa] (gauge), a second output (not scaled).
    bad_values : sequence of str
        The site's own bad-sample texts besides the historians' usual ones (see ``load_log``).
    fuel_temperature_col : str or None
        Fuel-temperature column [°C] (None: read none).
    flow_unit : str, optional
        Unit of the flow column when its name does not say it (``load_log``'s ``output_unit``).

    Raises
    ------
    DataError
        If the log has no fuel temperature and none is given, or cannot be read.
    """
    file = Path(path)

    def read(column: str, scale: Sequence[float] | None, unit: str | None) -> IOData:
        return load_log(
            file, time_col=time_col, input_col=input_col, output_col=column,
            sample_time=sample_time, input_scale=input_scale, output_scale=scale,
            fuel_temperature_col=fuel_temperature_col, bad_values=bad_values, max_gap=max_gap,
            output_unit=unit,
        )  # fmt: skip

    flow = read(output_col, output_scale, flow_unit)
    pressure = None if pressure_col is None else read(pressure_col, None, None)
    return calibration_log(file, flow, pressure, fuel_temp_C=fuel_temp_C)


def usable_samples(flow: IOData, name: str) -> tuple[int, list[str]]:
    """How many leading samples of ``flow`` a calibration uses, and the notes saying why.

    Gaps up to :data:`BRIDGE_MAX_PERIODS` sample periods are simulated through; the first longer
    one ends the usable part.
    """
    t = flow.t
    h = flow.sample_time
    notes: list[str] = []
    bridged: list[float] = []
    n = flow.n_samples
    for start in flow.segment_starts:
        gap = float(t[start] - t[start - 1])
        if gap <= BRIDGE_MAX_PERIODS * h * (1.0 + 1e-9):
            bridged.append(gap)
            continue
        n = start
        used, total = float(t[n - 1] - t[0]), float(t[-1] - t[0])
        notes.append(
            f"{name}: a gap of {gap:.3g} s at t = {float(t[n - 1]):.6g} s (longer than "
            f"{BRIDGE_MAX_PERIODS:g} sample periods) ends what can be calibrated: only the first "
            f"stretch is used, {n} of {flow.n_samples} samples ({used:.4g} of {total:.4g} s, "
            f"{100.0 * n / flow.n_samples:.0f} % of the log); the command during the gap is "
            "unknown and the stretch after it does not start at rest: cut the log into files "
            "that each start at rest, or shorten the gaps (--max-gap)"
        )
        break
    if bridged:
        notes.append(
            f"{name}: {len(bridged)} gap(s) of at most {max(bridged):.3g} s simulated through "
            "with the command held (the PLC holds it); their missing samples are not fitted"
        )
    return n, notes


def calibration_log(
    path: str | Path,
    flow: IOData,
    pressure: IOData | None = None,
    *,
    fuel_temp_C: float | None = None,
) -> CalibrationLog:
    """A loaded log (and its pressure, read as a second output of the same table) for calibration.

    Parameters
    ----------
    path : str or Path
        The log file (its name and hash are recorded).
    flow : IOData
        The command [V] and the flow [L/min], as :func:`~fuelid.io.logs.load_log` returns them.
    pressure : IOData, optional
        The same command and the pump outlet pressure [MPa].
    fuel_temp_C : float, optional
        The log's fuel temperature [°C]; default the mean of its fuel-temperature column.

    Raises
    ------
    DataError
        If there is no fuel temperature, or the pressure does not line up with the flow.
    """
    file = Path(path)
    notes = [note.replace(_JOINT_SEGMENTS, "") for note in flow.notes]
    n, gap_notes = usable_samples(flow, file.name)
    notes += gap_notes
    columns = [flow.y[:n]]
    if pressure is not None:
        # read as a second output of the same table: the two reads must share the time grid
        if pressure.n_samples < n or not np.array_equal(pressure.t[:n], flow.t[:n]):
            raise DataError(
                f"{file.name}: the pressure column does not line up with the flow (missing or "
                "bad values in other rows): clean the log's rows first"
            )
        columns.append(pressure.y[:n])
    if fuel_temp_C is not None and flow.T_fuel is not None:
        logged = float(np.mean(flow.T_fuel[:n])) - KELVIN
        if abs(logged - fuel_temp_C) > TEMPERATURE_SPREAD_K:
            notes.append(
                f"{file.name}: --fuel-temp {fuel_temp_C:g} °C overrides the log's own fuel "
                f"temperature column (mean {logged:.1f} °C)"
            )
    if fuel_temp_C is None:
        if flow.T_fuel is None:
            raise DataError(
                f"{file.name} has no fuel-temperature column: give its fuel temperature "
                "(--fuel-temp, one value per log); the plant's viscosity and density depend on it"
            )
        temps = flow.T_fuel[:n] - KELVIN
        fuel_temp_C = float(np.mean(temps))
        if float(np.ptp(temps)) > TEMPERATURE_SPREAD_K:
            notes.append(
                f"{file.name}: the fuel temperature spans {np.ptp(temps):.1f} K; the log is "
                f"calibrated at its mean {fuel_temp_C:.1f} °C"
            )
    if not math.isfinite(fuel_temp_C):
        raise DataError(f"{file.name}: the fuel temperature is not a number")
    record = Record.from_arrays(
        flow.t[:n],
        flow.u[:n],
        np.column_stack(columns),
        name=file.name,
        context={FUEL_TEMPERATURE_KEY: fuel_temp_C + KELVIN},
    )
    return CalibrationLog(file, _sha256(file), record, fuel_temp_C, tuple(notes))
