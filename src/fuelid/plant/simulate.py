"""Time-domain simulation of the nonlinear plant as the PLC sees it.

The controller output is piecewise constant (sample-and-hold), so the ODE is integrated segment by
segment between input changes with LSODA (scipy's ``odeint``, which switches to BDF when the fast
motor and hydraulic modes make the problem stiff) and the analytic Jacobian: one segment is
:func:`integrate_held`, which the closed loop (:mod:`fuelid.tuning.closedloop`) uses for each
control period too, and which refuses a failed solve with a ``FuelidError``. The meter's dead time
is applied exactly by evaluating the meter state at ``t_k − τ``; noise and quantisation are added
to the sampled reading. On request (``pressure=True``) the pump outlet pressure p is sampled at
``t_k`` itself (a pressure transmitter has no part of the flowmeter's dead time) and logged with
its own noise and quantisation (:meth:`SimulationResult.measure_pressure`). The fuel temperature
may follow a trajectory; it is held constant within each segment, and a new segment starts
whenever it has moved by ``temperature_resolution`` (0.05 K by default: the flow error of holding
it is then far below any meter's resolution).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.integrate
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import FuelidError
from fuelid.io.timeseries import (
    FUEL_TEMPERATURE_COLUMN,
    INPUT_COLUMN,
    OUTPUT_COLUMN,
    PRESSURE_COLUMN,
    TimeSeries,
)
from fuelid.lti import check_control_period
from fuelid.plant._config import PlantConfig
from fuelid.plant._flowmeter import measure_flow
from fuelid.plant._system import (
    STATE_NAMES,
    PlantCoefficients,
    measured_state,
    plant_coefficients,
    plant_jacobian,
    plant_rhs,
    steady_state,
)
from fuelid.profiles import InputProfile
from fuelid.units import LPM_PER_M3S, PA_PER_MPA
from fuelid.units import T0 as KELVIN

if TYPE_CHECKING:
    import pandas as pd

FloatArray = NDArray[np.float64]
#: absolute tolerances per state [Hz, rad/s, Pa, m³/s, m³/s]: far below noise and quantisation
ATOL = np.array([1e-6, 1e-5, 1e-1, 1e-10, 1e-10])
RTOL = 1e-7
MAX_STEPS = 100_000
"""Most internal steps LSODA may take between two output times before it gives up."""
SNAP = 1e-9  # [s]
PRESSURE_NOISE_STD = 2000.0
"""Default standard deviation of the logged pump pressure's white noise [Pa] (0.002 MPa)."""
PRESSURE_RESOLUTION = 100.0
"""Default quantisation step of the logged pump pressure [Pa] (0.0001 MPa)."""
PRESSURE_TRUTH_COLUMN = "p_true_MPa"
"""Noise-free pump pressure column of a log with truth [MPa]."""
_PRESSURE_STATE = STATE_NAMES.index("p")
_PRESSURE_STREAM = 1  # spawn key of the pressure noise's random stream (the flow's is the seed's)
_SOLVED = "Integration successful."  # odeint's message when LSODA returns istate = 2


@dataclass(frozen=True)
class FuelTemperature:
    """Fuel temperature over time [K]: constant, or linear interpolation of a trajectory.

    Examples
    --------
    >>> FuelTemperature.ramp(273.15, 293.15, 100.0).at(50.0)
    283.15
    """

    times: FloatArray
    values: FloatArray

    @classmethod
    def constant(cls, T: float) -> FuelTemperature:
        """The same temperature throughout [K]."""
        return cls(np.array([0.0]), np.array([float(T)]))

    @classmethod
    def ramp(cls, T_start: float, T_end: float, duration: float) -> FuelTemperature:
        """Linear change from ``T_start`` to ``T_end`` [K] over ``duration`` [s]."""
        return cls(np.array([0.0, duration]), np.array([float(T_start), float(T_end)]))

    @property
    def is_constant(self) -> bool:
        """True when the trajectory never changes."""
        return bool(np.all(self.values == self.values[0]))

    def at(self, t: ArrayLike) -> FloatArray | float:
        """Temperature at time(s) ``t`` [K], held at the ends."""
        out = np.interp(np.asarray(t, dtype=float), self.times, self.values)
        return float(out) if np.ndim(out) == 0 else out


@dataclass(frozen=True)
class SimulationResult:
    """A simulated PLC log (SI inside; :meth:`to_log` converts to the file columns)."""

    time: FloatArray
    """Sample times [s]."""
    u: FloatArray
    """Command held by the PLC at each sample [V]."""
    q_meter: FloatArray
    """Noise-free meter reading (lag and dead time applied) [m³/s]."""
    q_measured: FloatArray
    """Reading with noise and quantisation, as logged [m³/s]."""
    T_fuel: FloatArray
    """Fuel temperature [K]."""
    p_pump: FloatArray | None = None
    """Noise-free pump outlet pressure (gauge) at the sample times, no dead time [Pa]; None
    unless the run was asked for the pressure."""
    p_measured: FloatArray | None = None
    """Pump outlet pressure with noise and quantisation, as logged [Pa]; None: not logged."""

    def measure_pressure(
        self,
        noise_std: float = PRESSURE_NOISE_STD,
        resolution: float = PRESSURE_RESOLUTION,
        seed: int | None = None,
    ) -> SimulationResult:
        """A copy with a logged pump pressure: ``p_pump`` plus white noise, then quantised.

        Parameters
        ----------
        noise_std : float
            Standard deviation of the transmitter's white noise [Pa].
        resolution : float
            Quantisation step of the value the PLC reads [Pa]; 0 for none.
        seed : int, optional
            Seed of the noise (its stream is independent of the flow noise of the same seed).

        Returns
        -------
        SimulationResult
            A copy with ``p_measured`` set.

        Raises
        ------
        FuelidError
            If the run has no pump pressure, or noise or resolution is negative or not finite.
        """
        if self.p_pump is None:
            raise FuelidError("this simulation result has no pump pressure to measure")
        for name, value in (("noise", noise_std), ("resolution", resolution)):
            if not (math.isfinite(value) and value >= 0.0):
                raise FuelidError(f"pressure {name} must be zero or positive, got {value:g} Pa")
        stream = np.random.SeedSequence(seed, spawn_key=(_PRESSURE_STREAM,))
        rng = np.random.default_rng(stream)
        p = measure_flow(self.p_pump, noise_std, resolution, rng)  # the same A/D chain
        return dataclasses.replace(self, p_measured=p)

    def to_log(self, include_truth: bool = False) -> TimeSeries:
        """The PLC-like log: ``t_s``, ``u_V``, ``q_Lpm``, ``T_fuel_degC`` (+ ``q_true_Lpm``).

        With a logged pressure (``p_measured``) also ``p_pump_MPa`` (+ ``p_true_MPa``).
        """
        signals = {
            INPUT_COLUMN: self.u,
            OUTPUT_COLUMN: self.q_measured * LPM_PER_M3S,
            FUEL_TEMPERATURE_COLUMN: self.T_fuel - KELVIN,
        }
        units = {INPUT_COLUMN: "V", OUTPUT_COLUMN: "L/min", FUEL_TEMPERATURE_COLUMN: "degC"}
        if self.p_measured is not None:
            signals[PRESSURE_COLUMN] = self.p_measured / PA_PER_MPA
            units[PRESSURE_COLUMN] = "MPa"
        if include_truth:
            signals["q_true_Lpm"] = self.q_meter * LPM_PER_M3S
            units["q_true_Lpm"] = "L/min"
            if self.p_measured is not None and self.p_pump is not None:
                signals[PRESSURE_TRUTH_COLUMN] = self.p_pump / PA_PER_MPA
                units[PRESSURE_TRUTH_COLUMN] = "MPa"
        return TimeSeries(self.time, signals, units)

    def to_pandas(self) -> pd.DataFrame:
        """:meth:`to_log` as a DataFrame (noise-free reading included)."""
        return self.to_log(include_truth=True).to_pandas()


ProgressCallback = Callable[[float], None]


def simulate(
    config: PlantConfig,
    profile: InputProfile,
    *,
    T_fuel: FuelTemperature | float = 293.15,
    sample_time: float = 0.02,
    control_period: float = 1.0,
    noise_std: float | None = None,
    resolution: float | None = None,
    seed: int | None = None,
    temperature_resolution: float = 0.05,
    progress: ProgressCallback | None = None,
    pressure: bool = False,
    pressure_noise_std: float = PRESSURE_NOISE_STD,
    pressure_resolution: float = PRESSURE_RESOLUTION,
) -> SimulationResult:
    """Simulate the nonlinear plant and sample it as the PLC does.

    The plant starts at its steady state for the first command and the initial fuel temperature.

    Parameters
    ----------
    config : PlantConfig
        The plant.
    profile : InputProfile
        Commands [V]; aligned to ``control_period`` (sample-and-hold of the controller output).
    T_fuel : FuelTemperature or float
        Fuel temperature [K], constant or a trajectory.
    sample_time : float
        PLC sampling interval of the log [s] (0.02 s by default).
    control_period : float
        Period at which the controller output changes [s]; 0 for none (changes applied when given).
    noise_std : float, optional
        Flowmeter noise standard deviation [m³/s]; the config's ``noise_std_Lpm`` when None.
    resolution : float, optional
        Quantisation step of the reading [m³/s]; the config's ``resolution_Lpm`` when None.
    seed : int, optional
        Seed of the noise, for reproducible logs.
    temperature_resolution : float
        Largest change of a varying fuel temperature within one integration segment [K]; the
        plant uses the temperature at the middle of each segment.
    progress : callable, optional
        Called with the fraction of simulated time done, after every segment.
    pressure : bool
        Also sample the pump outlet pressure at the sample times (``p_pump``, no dead time) and
        log it with noise and quantisation (``p_measured``). The flow is then evaluated at a
        few more solver output times, which moves it by far less than the solver tolerance.
    pressure_noise_std : float
        Standard deviation of the logged pressure's noise [Pa] (0.002 MPa by default).
    pressure_resolution : float
        Quantisation step of the logged pressure [Pa] (0.0001 MPa by default).

    Returns
    -------
    SimulationResult

    Raises
    ------
    FuelidError
        On a command outside the drive's signal range, a non-positive sample time, a fuel
        temperature outside the fuel correlation's range, or a failed ODE solve
        (:func:`integrate_held`).
    """
    if not (math.isfinite(sample_time) and sample_time > 0.0):
        raise FuelidError(f"sample time must be positive, got {sample_time:g} s")
    if not (math.isfinite(temperature_resolution) and temperature_resolution > 0.0):
        raise FuelidError(
            f"temperature resolution must be positive, got {temperature_resolution:g} K"
        )
    check_control_period(control_period)
    lo, hi = profile.u_range
    u_min, u_max = config.vfd.u_min_V, config.vfd.u_max_V
    if lo < u_min or hi > u_max:
        raise FuelidError(
            f"the input profile spans {lo:g}…{hi:g} V, outside the drive's signal range "
            f"{u_min:g}…{u_max:g} V"
        )
    temperature = (
        T_fuel if isinstance(T_fuel, FuelTemperature) else FuelTemperature.constant(T_fuel)
    )
    applied = profile.aligned(control_period)
    n_samples = math.floor(profile.duration / sample_time + 1e-9) + 1
    time = np.round(np.arange(n_samples) * sample_time, 12)
    coefficients = _CoefficientCache(config)
    c0 = coefficients.at(float(temperature.at(0.0)))
    delay = c0.delay
    # the meter reads q_m (or q) τ late; a pressure transmitter reads p on time: with the
    # pressure, one integration evaluated at the union of both sets of times
    delayed = np.round(time - delay, 12) if pressure else time - delay
    wanted = np.unique(np.concatenate((delayed, time))) if pressure else delayed
    states = _integrate(
        applied, temperature, coefficients, wanted, temperature_resolution, progress
    )
    q_meter = states[np.searchsorted(wanted, delayed), measured_state(c0)]
    p_pump = states[np.searchsorted(wanted, time), _PRESSURE_STATE] if pressure else None
    meter = config.flowmeter
    std = meter.noise_std_Lpm / LPM_PER_M3S if noise_std is None else noise_std
    step = meter.resolution_Lpm / LPM_PER_M3S if resolution is None else resolution
    if std < 0.0 or step < 0.0:
        raise FuelidError("noise and resolution must not be negative")
    rng = np.random.default_rng(seed)
    q_measured = measure_flow(q_meter * LPM_PER_M3S, std * LPM_PER_M3S, step * LPM_PER_M3S, rng)
    result = SimulationResult(
        time=time,
        u=applied.at(time),
        q_meter=q_meter,
        q_measured=q_measured / LPM_PER_M3S,
        T_fuel=np.asarray(temperature.at(time), dtype=float) * np.ones_like(time),
        p_pump=p_pump,
    )
    if pressure:
        return result.measure_pressure(pressure_noise_std, pressure_resolution, seed)
    return result


def integrate_held(x0: FloatArray, times: FloatArray, u: float, c: PlantCoefficients) -> FloatArray:
    """Integrate the plant ODE with the command held, from ``x0`` at ``times[0]``.

    LSODA (:func:`scipy.integrate.odeint`) on :func:`~fuelid.plant._system.plant_rhs` with the
    analytic Jacobian :func:`~fuelid.plant._system.plant_jacobian`, to the tolerances
    :data:`RTOL` and :data:`ATOL`, at most :data:`MAX_STEPS` steps between output times. This is
    the one place the nonlinear plant is integrated: :func:`simulate` calls it per segment and
    :func:`fuelid.tuning.closedloop.simulate_closed_loop` per control period.

    Parameters
    ----------
    x0 : ndarray, shape (5,)
        State ``[f, ω_m, p, q, q_m]`` at ``times[0]`` (SI).
    times : ndarray, shape (n,)
        Increasing output times [s], the start first (n ≥ 2).
    u : float
        Drive command held over the whole span [V].
    c : PlantCoefficients
        The plant at the fuel temperature of the span.

    Returns
    -------
    ndarray, shape (n, 5)
        The state at each of ``times``; row 0 is ``x0``.

    Raises
    ------
    FuelidError
        If the solver fails (too much work, an unreachable tolerance, illegal input …).

    Examples
    --------
    From rest at 3 V nothing moves:

    >>> from fuelid.plant import load_plant_config
    >>> from fuelid.plant import plant_coefficients, steady_state
    >>> c = plant_coefficients(load_plant_config(), 293.15)
    >>> x0 = steady_state(3.0, c).state
    >>> states = integrate_held(x0, np.array([0.0, 0.5, 1.0]), 3.0, c)
    >>> states.shape, bool(np.allclose(states, x0, rtol=1e-9, atol=1e-12))
    ((3, 5), True)
    """
    with warnings.catch_warnings():
        # a failed solve is reported below, as a FuelidError, not as a warning
        warnings.simplefilter("ignore", scipy.integrate.ODEintWarning)
        states, info = scipy.integrate.odeint(
            plant_rhs,
            x0,
            times,
            args=(u, c),
            Dfun=plant_jacobian,
            tfirst=True,
            rtol=RTOL,
            atol=ATOL,
            mxstep=MAX_STEPS,
            full_output=True,
        )
    if info["message"] != _SOLVED:
        raise FuelidError(
            f"the ODE solver failed on {times[0]:g}…{times[-1]:g} s at u = {u:g} V: "
            f"{info['message']}"
        )
    solved: FloatArray = states
    return solved


class _CoefficientCache:
    """Plant coefficients per fuel temperature, computed once per distinct value (to 1 mK)."""

    def __init__(self, config: PlantConfig) -> None:
        self._config = config
        self._cache: dict[float, PlantCoefficients] = {}

    def at(self, T: float) -> PlantCoefficients:
        key = round(T, 3)
        if key not in self._cache:
            self._cache[key] = plant_coefficients(self._config, key)
        return self._cache[key]


def _segment_bounds(
    profile: InputProfile, temperature: FuelTemperature, resolution: float
) -> FloatArray:
    """Times where the integration restarts.

    Every input change, and while T_fuel changes, every time it has moved by ``resolution`` [K]
    since the last restart (found on a 0.1 s grid).
    """
    bounds: list[FloatArray] = [profile.t, np.array([profile.duration])]
    if not temperature.is_constant:
        grid = np.linspace(0.0, profile.duration, max(2, math.ceil(profile.duration / 0.1) + 1))
        T = np.asarray(temperature.at(grid), dtype=float)
        cuts = [0]
        for k in range(1, grid.size):
            if abs(T[k] - T[cuts[-1]]) >= resolution:
                cuts.append(k)
        bounds.append(grid[cuts])
    return np.unique(np.round(np.concatenate(bounds), 12))


def _integrate(
    profile: InputProfile,
    temperature: FuelTemperature,
    coefficients: _CoefficientCache,
    t_eval: FloatArray,
    temperature_resolution: float,
    progress: ProgressCallback | None,
) -> FloatArray:
    """The state at the (sorted) times ``t_eval``, shape (n, 5); before t = 0 it is at rest."""
    c = coefficients.at(float(temperature.at(0.0)))
    x = steady_state(float(profile.u[0]), c).state
    out = np.tile(x, (t_eval.size, 1))
    bounds = _segment_bounds(profile, temperature, temperature_resolution)
    total = float(bounds[-1])
    for a, b in itertools.pairwise(bounds):
        mid = 0.5 * (a + b)
        u = float(profile.at(mid))
        c = coefficients.at(float(temperature.at(mid)))
        # evaluation times closer than SNAP to a segment end count as that end (LSODA refuses
        # output times within rounding of its start)
        first, last = np.searchsorted(t_eval, [a - SNAP, b - SNAP], side="left")
        at_start = first + int(np.searchsorted(t_eval[first:last], a + SNAP, side="left"))
        out[first:at_start] = x
        inside = t_eval[at_start:last]
        states = integrate_held(x, np.concatenate(([a], inside, [b])), u, c)
        out[at_start:last] = states[1:-1]
        x = states[-1]
        if progress is not None:
            progress(b / total)
    # times at the end of the run belong to no segment (each takes [a, b)): the final state
    out[np.searchsorted(t_eval, total - SNAP, side="left") :] = x
    return out
