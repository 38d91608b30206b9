"""The virtual PLC's engine: the nonlinear fuel loop with its PLC emulated, free of any protocol.

Synchronous and deterministic given the seed: the same writes at the same plant times give the
same samples, whatever the speed and however :meth:`VirtualPLC.advance` is sliced. A protocol
front end (:mod:`fuelid.plc.virtual._frontend`) and the runner (:mod:`fuelid.plc.virtual._runner`)
put it on a socket.

Time. Sample ``k`` is taken at plant time ``t_k = k·plant_period_s`` (``k·period_s`` on the PLC's
clock, the same with an exact clock, see below); its sequence number is
``(seq0 + k) mod 2**32``. Every ``control_period_s`` (sample k a multiple of
``n = control_period_s/period_s``) the PLC scans: it reads the write area (what clients wrote by
then), the flow reading of that sample, runs the PI (or takes the manual command) and holds the
command over the next ``n`` samples. The plant (:func:`fuelid.plant.simulate.integrate_held`, the
same nonlinear ODE as ``fuelid simulate``) is therefore integrated once per control period with the
``n + 1`` sample times as its output times, not once per sample, which is what makes 50–1000 times
real time possible. The fuel temperature is held within a control period at its midpoint value.

The PLC's clock (exact by default). With ``clock_slow`` = s the PLC's clock runs slow by the
fraction s: a period of its clock, ``period_s``, lasts ``period_s·(1 + s)`` of real time (0.02: its
20 ms cyclic task takes 20.4 ms; negative: a fast clock). The plant is physics and runs in real
time: it is integrated, delayed, disturbed and warmed over ``plant_period_s = period_s·(1 + s)``
per sample. The PLC's logic runs on its own clock: the PI's period and integral, the heartbeat
timeout, the profiles it plays, :attr:`VirtualPLC.time_s`. The runner
(:mod:`fuelid.plc.virtual._runner`) paces its ticks by ``plant_period_s`` of wall time, so a client
that times samples by their receipt (a recorder without ring or ``seq``) sees ``plant_period_s``
between them. With s = 0 the two periods are the same number and nothing changes.

Measurement. The reading of sample k is the meter state ``delay`` earlier (linear interpolation
between samples), plus white noise (a seeded :class:`numpy.random.Generator`), then quantised as a
Siemens analog input: 0…27648 counts = 0…120 L/min (``flow_counts``, int16), ``flow`` being the
same counts in L/min.

Disturbance (off by default). With ``disturbance_sd_Lpm`` > 0 a slow coloured disturbance d is
added to the flow the meter sees, before the white noise: a first-order autoregressive (AR(1),
sampled Ornstein–Uhlenbeck) sequence per sample, d_k = φ·d_{k−1} + σ·√(1 − φ²)·e_k with
φ = exp(−plant_period_s/``disturbance_time_s``), e_k standard normal from the same seeded generator,
d_0 = 0; its stationary standard deviation is σ = ``disturbance_sd_Lpm`` and its correlation
time ``disturbance_time_s``. The PI acts on the reading, so in AUTO it fights d (a load the loop
must reject, as a drifting pump or a valve elsewhere in the line would be); in MAN it is seen
only. It is part of the flow, so :meth:`VirtualPLC.clean_readings` contains it. With σ = 0 (the
default) nothing is drawn and the samples are exactly those without the option.

The PLC's rules (docs/tutorials/plc-link.md).

- PI, ideal form u = Kc·(e + (1/Ti)∫e dt), e = setpoint − flow, at the control period:
  :class:`fuelid.tuning._controller.DiscretePI`, the positional algorithm with a forward-Euler
  integral in output units, the drive's 1–5 V signal range as output limits and
  **back-calculation anti-windup** with tracking time Tt = h (the integral is pulled back so that
  the unlimited output equals the limited one within one period: no windup tail).
- MAN/AUTO: ``mode_request`` 0 = MAN, 1 = AUTO, other values ignored. In MAN the command is
  ``manual_command`` clamped to 1–5 V. MAN → AUTO is bumpless: the integral starts at
  ``u − Kc·e`` so the first AUTO output equals the last manual one. A setpoint profile forces
  AUTO and a command profile MAN (they script the operator); the setpoint is
  ``setpoint_request`` unless a setpoint profile plays.
- Staged gains: a change of ``apply`` (to any value other than the last one seen) takes
  ``staged_kc`` and ``staged_ti`` at the next scan, provided the heartbeat is fresh. A set that is
  not finite and positive is refused: status bit 2 set, nothing applied, ``echo`` unchanged. A
  valid set is clamped to the PLC's own limits, 0.1–10 times the commissioning gains, applied
  bumplessly (integral ``I += (Kc_old − Kc_new)·e``, so the output of that scan is the one the
  old gains give) and echoed whole (``kc``, ``ti`` and ``echo`` = the apply number, status bit 2
  cleared). A change of ``apply`` while the heartbeat is stale is refused as well (bit 2).
- Heartbeat: the advisor increments ``heartbeat``; it is fresh while it changed less than
  ``heartbeat_timeout_s`` of plant time ago. Until it first changes it is stale (no advisor has
  proven it is alive, so no staged set is taken). While stale, status bit 1 is set; with
  ``restore_on_stale`` the commissioning gains are restored, bumplessly, and ``echo`` reset to 0.
- Status (uint16): bit 0 the output at a limit, bit 1 heartbeat stale, bit 2 the last staged set
  refused.
- Excitation on demand: at each scan the PLC reads ``excitation_request`` [V] (level-triggered,
  as the setpoint) and applies it clamped to ±``excitation_limit_V`` (its own limit, 0.5 V by
  default); it applies 0 when the request is not finite or the heartbeat is stale (the same
  :meth:`VirtualPLC.heartbeat_stale` and ``heartbeat_timeout_s`` as the staged gains: a test
  signal left behind by an advisor that died stops within the timeout), and it then clears the
  request itself, so that an advisor whose heartbeat comes back does not find its old signal
  applied again before it writes a new one. The applied signal is
  added to the PI's output (AUTO) or to the manual command (MAN) and the sum clamped to the
  drive's 1–5 V: ``command`` (the read point and the ring field) is the VFD command actually
  applied, the sum after the clamp, held over the control period like any command, and
  ``excitation`` (the read point and the ring field) the signal applied at that scan, held
  likewise. The PI does not see the added signal: its integral, its anti-windup (which tracks
  the PI's own limited output) and the bumpless MAN → AUTO start (from the last manual command
  without the signal) are the PI's alone, because the signal is an external input added after
  the PI, not part of its output; near a drive limit the sum is clipped and ``command`` moves
  by less than ``excitation`` says (which is the signal after the PLC's own clamp and zeroing,
  not after the drive's), so keeping the margin to the limits is fuelid's job. With
  ``excitation_request`` never written (0) the samples are exactly those without the feature.
- Run flag: ``run`` is 1 inside one of the ``run_windows`` ([start, end) on the PLC's clock [s])
  or while :meth:`VirtualPLC.set_run` holds it, else 0. The virtual PLC does *not* zero the test
  signal during a run: fuelid must stop exciting when ``run`` rises. A real PLC may add that
  interlock (zero the signal while the tunnel runs); fuelid must not rely on it.

Examples
--------
>>> plc = VirtualPLC(seed=1)
>>> plc.write_points({"manual_command": 3.0})
>>> records = plc.advance(500)          # 10 s of plant time
>>> plc.seq, len(records), round(plc.read_points()["command"], 3)
(500, 500, 3.0)
>>> plc.write_points({"heartbeat": 1, "excitation_request": 0.8})   # clamped to 0.5 V
>>> _ = plc.advance(50)                 # the next scan
>>> plc.read_points()["excitation"], round(plc.read_points()["command"], 3)
(0.5, 3.5)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import ConfigError, DataError
from fuelid.plant import (
    PlantConfig,
    load_plant_config,
    measured_state,
    plant_coefficients,
    steady_state,
)
from fuelid.plant.simulate import FuelTemperature, integrate_held
from fuelid.plc.virtual._analog import from_counts, to_counts
from fuelid.plc.virtual._commissioning import commissioning_gains as commissioning_gains
from fuelid.plc.virtual._options import (
    ProfileLike,
    fuel_temperature_trajectory,
    positive,
    run_windows_checked,
    setpoint_and_command_profiles,
)
from fuelid.plc.virtual._points import (
    DEFAULT_RING_SIZE,
    FLOW_COUNTS,
    FUEL_TEMPERATURE_COUNTS,
    POINTS,
    RING_FIELDS,
)
from fuelid.profiles.runs import Profile
from fuelid.tuning import DiscretePI, PISettings
from fuelid.tuning.closedloop import steady_command
from fuelid.units import (
    DEFAULT_FUEL_TEMPERATURE_C,
    LPM_PER_M3S,
    kelvin_to_celsius,
)

FloatArray = NDArray[np.float64]

SEQ_MODULUS = 2**32
"""The sequence counter is a uint32: it wraps to 0 after 2**32 − 1."""
STATUS_AT_LIMIT = 1
"""Status bit 0: the command sits at a limit of the 1–5 V range."""
STATUS_STALE = 2
"""Status bit 1: the advisor's heartbeat is stale."""
STATUS_REFUSED = 4
"""Status bit 2: the last staged set was refused."""
GAIN_LIMITS = (0.1, 10.0)
"""The PLC clamps a staged Kc and Ti to these multiples of its commissioning values."""
MAX_RING_SIZE = 6400
"""Most records in the ring: 1000 + 10·6400 registers stay inside the Modbus address space."""
DEFAULT_EXCITATION_LIMIT_V = 0.5
"""The PLC's own clamp of the test signal it adds to its PI output [V]."""
TEMPERATURE_RESOLUTION_K = 0.01
"""The plant coefficients are re-evaluated when the fuel temperature has moved this much [K]."""
MAX_CLOCK_SLOW = 0.5
"""``clock_slow`` stays within ±this fraction: beyond, it is another period, not a clock error."""
MAN, AUTO = 0, 1

READ_POINTS = tuple(name for name, point in POINTS.items() if point.access == "read")
WRITE_POINTS = tuple(name for name, point in POINTS.items() if point.access == "write")


class VirtualPLC:
    """The fuel loop and its PLC, advanced sample by sample in plant time.

    Parameters
    ----------
    config : PlantConfig, optional
        The plant; the packaged reference plant when None.
    period_s : float
        Sample period [s]: one ring record per period.
    control_period_s : float
        The PLC's scan of the PI [s]; a whole multiple of ``period_s``.
    fuel_temp_C : float
        Constant fuel temperature [°C] (when no profile is given).
    fuel_temp_profile : Profile, (times [s], temperatures [°C]) or FuelTemperature, optional
        Fuel-temperature drift: interpolated, held after its end. A
        :class:`~fuelid.plant.simulate.FuelTemperature` is in kelvin.
    setpoint_profile : "run", Profile or (times [s], setpoints [L/min]), optional
        A setpoint profile, repeated; "run" is :func:`~fuelid.profiles.runs.run_profile`.
        The PLC runs in AUTO while it plays.
    command_profile : "steps", Profile or (times [s], commands [V]), optional
        A manual command profile, repeated; "steps" is
        :func:`~fuelid.profiles.runs.steps_profile`. The PLC runs in MAN while it plays.
    seed : int, optional
        Seed of the measurement noise (None: fresh entropy).
    ring_size : int
        Records in the ring buffer (2…6400).
    kc, ti : float, optional
        Commissioning gains, Kc [V per L/min] and Ti [s]; default cautious SIMC
        (:func:`commissioning_gains`, τc = 2θ) at the initial fuel temperature.
    heartbeat_timeout_s : float
        Plant time without a heartbeat change after which it is stale [s].
    restore_on_stale : bool
        Restore the commissioning gains when the heartbeat goes stale.
    noise_sd_Lpm : float, optional
        Standard deviation of the flowmeter's white noise [L/min]; default the plant's
        ``flowmeter.noise_std_Lpm`` (0.1 L/min for the reference plant).
    quantisation : bool
        Quantise the flow reading to the analog input's counts (0…27648 = 0…120 L/min,
        0.0043 L/min a count); ``flow_counts`` is quantised always.
    seq0 : int
        Sequence number of the first sample (tests of the 2**32 wrap-around).
    keep_clean_readings : bool
        Keep the noise-free reading of every sample (:meth:`clean_readings`).
    disturbance_sd_Lpm : float
        Standard deviation of the slow coloured (AR(1)) flow disturbance [L/min] (module
        docstring, "Disturbance"); 0 (the default): none.
    disturbance_time_s : float
        Its correlation time [s] (plant time), > 0.
    clock_slow : float
        How slow the PLC's clock runs, a fraction within (−0.5, 0.5): a period of its clock
        (``period_s``) lasts ``period_s·(1 + clock_slow)`` of real (plant) time; 0.02 is a clock
        2 % slow (its 20 ms cycle 20.4 ms), negative a fast one; 0 (the default): exact (module
        docstring, "The PLC's clock").
    excitation_limit_V : float
        The PLC's own clamp of the test signal [V], finite and > 0: ``excitation_request`` is
        applied within ±this (module docstring, "Excitation on demand").
    run_windows : sequence of (float, float)
        Wind-tunnel runs, [start, end) on the PLC's clock [s] (finite, start < end): the read
        point ``run`` is 1 inside one (or while :meth:`set_run` holds it).

    Raises
    ------
    ConfigError
        If a period, the ring size, a profile, a gain, the excitation limit or a run window is
        not acceptable.
    """

    def __init__(
        self,
        config: PlantConfig | None = None,
        *,
        period_s: float = 0.02,
        control_period_s: float = 1.0,
        fuel_temp_C: float = DEFAULT_FUEL_TEMPERATURE_C,
        fuel_temp_profile: Profile | FuelTemperature | tuple[ArrayLike, ArrayLike] | None = None,
        setpoint_profile: str | ProfileLike | None = None,
        command_profile: str | ProfileLike | None = None,
        seed: int | None = 0,
        ring_size: int = DEFAULT_RING_SIZE,
        kc: float | None = None,
        ti: float | None = None,
        heartbeat_timeout_s: float = 10.0,
        restore_on_stale: bool = False,
        noise_sd_Lpm: float | None = None,
        quantisation: bool = True,
        seq0: int = 0,
        keep_clean_readings: bool = False,
        disturbance_sd_Lpm: float = 0.0,
        disturbance_time_s: float = 60.0,
        clock_slow: float = 0.0,
        excitation_limit_V: float = DEFAULT_EXCITATION_LIMIT_V,
        run_windows: Sequence[tuple[float, float]] = (),
    ) -> None:
        self.config = config if config is not None else load_plant_config()
        n_control = _control_steps(period_s, control_period_s)
        _check_ring_heartbeat_clock(ring_size, heartbeat_timeout_s, clock_slow)
        self.excitation_limit_V = positive("excitation_limit_V", excitation_limit_V)
        """The PLC's own clamp of the test signal [V]."""
        self.run_windows = run_windows_checked(run_windows)
        """The wind-tunnel runs, ((start, end), …) on the PLC's clock [s]."""
        self._run_by_hand = False
        self.period_s = float(period_s)
        self.clock_slow = float(clock_slow)
        self.plant_period_s = self.period_s * (1.0 + self.clock_slow)
        """Real (plant) time between samples [s]: ``period_s`` of the PLC's clock."""
        self.control_period_s = float(control_period_s)
        self.n_control = n_control
        self.ring_size = int(ring_size)
        self.heartbeat_timeout_s = float(heartbeat_timeout_s)
        self.restore_on_stale = restore_on_stale
        self.quantisation = quantisation
        self._set_measurement(noise_sd_Lpm, disturbance_sd_Lpm, disturbance_time_s)
        self._rng = np.random.default_rng(seed)
        self._temperature = fuel_temperature_trajectory(fuel_temp_C, fuel_temp_profile)
        self._sp_profile, self._u_profile = setpoint_and_command_profiles(
            setpoint_profile, command_profile
        )
        for T in (float(np.min(self._temperature.values)), float(np.max(self._temperature.values))):
            plant_coefficients(self.config, T)  # refuses a temperature outside the fuel's range
        T0 = float(self._temperature.at(0.0))
        self._coefficients = plant_coefficients(self.config, T0)
        self.u_min = float(self.config.vfd.u_min_V)
        self.u_max = float(self.config.vfd.u_max_V)
        self.kc0, self.ti0 = self._commissioning(kc, ti, T0)
        self._clear_write_area()
        self._start_plant(self._initial_command(T0), seq0, keep_clean_readings)

    def _set_measurement(
        self, noise_sd_Lpm: float | None, disturbance_sd_Lpm: float, disturbance_time_s: float
    ) -> None:
        """The meter's white noise and the slow AR(1) disturbance (module docstring)."""
        meter = self.config.flowmeter
        self.noise_sd_Lpm = float(meter.noise_std_Lpm if noise_sd_Lpm is None else noise_sd_Lpm)
        if not (math.isfinite(self.noise_sd_Lpm) and self.noise_sd_Lpm >= 0.0):
            raise ConfigError("noise_sd_Lpm must be zero or positive")
        if not (math.isfinite(disturbance_sd_Lpm) and disturbance_sd_Lpm >= 0.0):
            raise ConfigError("disturbance_sd_Lpm must be zero or positive")
        if not (math.isfinite(disturbance_time_s) and disturbance_time_s > 0.0):
            raise ConfigError("disturbance_time_s must be positive")
        self.disturbance_sd_Lpm = float(disturbance_sd_Lpm)
        self.disturbance_time_s = float(disturbance_time_s)
        self._disturbance_phi = math.exp(-self.plant_period_s / self.disturbance_time_s)
        self._disturbance = 0.0  # d of the last sample read [L/min]

    def _commissioning(self, kc: float | None, ti: float | None, T0: float) -> tuple[float, float]:
        """The commissioning gains: those given, the others cautious SIMC at ``T0`` [K]."""
        if kc is None or ti is None:
            kc_simc, ti_simc = commissioning_gains(self.config, T0, self.control_period_s)
            kc = kc_simc if kc is None else kc
            ti = ti_simc if ti is None else ti
        for name, value in (("kc", kc), ("ti", ti)):
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"{name} must be finite and positive, got {value!r}")
        return float(kc), float(ti)

    def _clear_write_area(self) -> None:
        """The write area as a fresh front end holds it (all zeros), and what the PLC made of it.

        Level-triggered points are read from it at every scan, edge-triggered ones (apply,
        heartbeat) compared with it.
        """
        self._writes: dict[str, float] = dict.fromkeys(WRITE_POINTS, 0.0)
        self._apply_seen = 0.0
        self._heartbeat_at: float | None = None  # plant time of the last heartbeat change [s]
        self._refused = False
        self._echo = 0.0
        self._setpoint = 0.0
        self._manual = self.u_min
        self._excitation = 0.0  # the test signal applied at the last scan [V]

    def _initial_command(self, T0: float) -> float:
        """The command [V] the plant starts at rest with, and the mode the PLC starts in."""
        if self._sp_profile is not None:
            self._mode = AUTO
            self._setpoint = self._sp_profile.at(0.0)
            return self._steady_command(self._setpoint, T0)
        self._mode = MAN  # a command profile, or mode_request 0 in a fresh write area
        if self._u_profile is not None:
            return float(np.clip(self._u_profile.at(0.0), self.u_min, self.u_max))
        return self.u_min  # manual_command 0, clamped to the range

    def _start_plant(self, u0: float, seq0: int, keep_clean_readings: bool) -> None:
        """The PI, the plant at steady state at ``u0`` [V], the ring and sample 0."""
        self._u = u0  # the VFD command applied: the PI's or manual command plus the test signal
        self._u_base = u0  # the same without the test signal (the PI's own output in AUTO)
        self._pi = DiscretePI(
            PISettings("commissioning", self.kc0, self.ti0, self.control_period_s),
            self.u_min,
            self.u_max,
            u0=u0,
        )
        self._x = steady_state(u0, self._coefficients).state

        self._seq0 = int(seq0) % SEQ_MODULUS
        self._k = 0
        # the meter's reading without noise or quantisation, per sample (tests of estimators
        # compare with the fit a noise-free reading gives); off by default: it grows
        self._clean: list[FloatArray] | None = [] if keep_clean_readings else None
        self.ring = np.zeros((self.ring_size, len(RING_FIELDS)))
        # the meter state at the samples, for the reading `delay` later: a short history
        self._delay_samples = self._coefficients.delay / self.plant_period_s
        self._history_len = math.ceil(self._delay_samples) + self.n_control + 3
        self._history = np.full(self._history_len, self._x[measured_state(self._coefficients)])
        self._history_first_k = -self._history_len + 1  # history[i] is sample first_k + i
        self._span_k0 = 0
        self._span_y = np.zeros(self.n_control)
        self._span_counts = np.zeros(self.n_control)
        self._span_T = np.zeros(self.n_control)
        self._start_span(0)
        self._take_sample(0)

    # -- what clients see ------------------------------------------------------------------

    @property
    def seq(self) -> int:
        """Sequence number of the newest sample (uint32, wraps at 2**32)."""
        return (self._seq0 + self._k) % SEQ_MODULUS

    @property
    def time_s(self) -> float:
        """Time of the newest sample since start on the PLC's clock [s] (plant time when exact)."""
        return self._k * self.period_s

    @property
    def gains(self) -> tuple[float, float]:
        """The PI gains applied: Kc [V per L/min], Ti [s]."""
        return self._pi.Kc, self._pi.Ti

    def clean_readings(self) -> FloatArray:
        """The noise-free flow reading of samples 0 … k [L/min] (``keep_clean_readings``).

        Sample k has sequence number ``(seq0 + k) % 2**32``: what the meter would show without
        noise and quantisation, for comparing an estimate with the one noise-free data give.
        """
        if self._clean is None:
            raise ConfigError("the engine was made without keep_clean_readings=True")
        return np.concatenate(self._clean)[: self._k + 1] if self._clean else np.zeros(0)

    def set_plant(self, config: PlantConfig) -> None:
        """Change the plant from the next control period on (pump wear, a new nozzle).

        The state (speed, flow, pressures, meter) carries over; the new coefficients apply from
        the next scan at the current fuel temperature.
        """
        T = float(self._coefficients.T_fuel)
        coefficients = plant_coefficients(config, T)
        if coefficients.delay != self._coefficients.delay:
            raise ConfigError("set_plant cannot change the meter's dead time while running")
        self.config = config
        self._coefficients = coefficients

    @property
    def run(self) -> bool:
        """True during a wind-tunnel run: inside a run window, or while :meth:`set_run` holds it."""
        if self._run_by_hand:
            return True
        t = self.time_s
        return any(start <= t < end for start, end in self.run_windows)

    def set_run(self, flag: bool) -> None:
        """Raise (True) or lower (False) the run flag by hand, as a tunnel's operator would.

        The read point ``run`` is 1 while it is raised, and inside the ``run_windows`` whatever
        it is; it changes nothing else (the PLC goes on adding the test signal).
        """
        self._run_by_hand = bool(flag)

    def heartbeat_stale(self) -> bool:
        """True when no heartbeat change came within the timeout (or none ever came)."""
        if self._heartbeat_at is None:
            return True
        return self.time_s - self._heartbeat_at > self.heartbeat_timeout_s

    def write_points(self, values: Mapping[str, float]) -> None:
        """Write points by name (write access only); the PLC acts on them at its next scan.

        Raises
        ------
        DataError
            If a name is not a write point.
        """
        for name, value in values.items():
            if name not in self._writes:
                raise DataError(
                    f"{name!r} is not a write point of the virtual PLC; they are "
                    f"{', '.join(WRITE_POINTS)}"
                )
            value = float(value)
            if name == "heartbeat" and value != self._writes[name]:
                self._heartbeat_at = self.time_s
            self._writes[name] = value

    def read_points(self) -> dict[str, float]:
        """Every read point by name, in engineering units, as of the newest sample."""
        i = self._k - self._span_k0
        status = 0
        if self._u <= self.u_min or self._u >= self.u_max:
            status |= STATUS_AT_LIMIT
        if self.heartbeat_stale():
            status |= STATUS_STALE
        if self._refused:
            status |= STATUS_REFUSED
        T_C = kelvin_to_celsius(float(self._span_T[i]))
        kc, ti = self.gains
        return {
            "seq": float(self.seq),
            "flow": float(self._span_y[i]),
            "command": self._u,
            "setpoint": self._setpoint,
            "fuel_temperature": T_C,
            "mode": float(self._mode),
            "status": float(status),
            "kc": kc,
            "ti": ti,
            "echo": self._echo,
            "flow_counts": float(self._span_counts[i]),
            "fuel_temperature_counts": float(to_counts(T_C, FUEL_TEMPERATURE_COUNTS)),
            "excitation": self._excitation,
            "run": 1.0 if self.run else 0.0,
            "ring_head": float(self.seq),
            "ring_size": float(self.ring_size),
        }

    def advance(self, n_samples: int) -> dict[int, FloatArray]:
        """Advance plant time by ``n_samples`` sample periods.

        Returns
        -------
        dict
            The new ring records by slot (``seq % ring_size``), each ``[seq, command [V],
            flow [L/min], setpoint [L/min], excitation [V]]``, oldest first; with more than
            ``ring_size`` samples only the newest record of each slot is there.
        """
        records: dict[int, FloatArray] = {}
        for _ in range(int(n_samples)):
            self._k += 1
            if self._k - self._span_k0 >= self.n_control:
                self._start_span(self._k)
            slot = self._take_sample(self._k)
            records.pop(slot, None)  # keep oldest-first order when a slot comes round again
            records[slot] = self.ring[slot].copy()
        return records

    # -- the PLC's scan and the plant ------------------------------------------------------

    def _steady_command(self, flow_Lpm: float, T: float) -> float:
        try:
            return steady_command(self.config, flow_Lpm, T)
        except ValueError:  # outside what the plant delivers: start at the nearest limit
            q_min = steady_state(self.u_min, self._coefficients).q * LPM_PER_M3S
            return self.u_min if flow_Lpm <= q_min else self.u_max

    def _meter(self, k: float) -> float:
        """The meter state at (fractional) sample ``k`` from the history [m³/s]."""
        j = k - self._history_first_k
        j0 = math.floor(j)
        frac = j - j0
        h = self._history
        j0 = max(j0, 0)
        if frac <= 0.0 or j0 + 1 >= h.size:
            return float(h[min(j0, h.size - 1)])
        return float(h[j0] + frac * (h[j0 + 1] - h[j0]))

    def _readings(self, k0: int, n: int) -> tuple[FloatArray, FloatArray]:
        """Flow readings [L/min] and their counts of samples k0 … k0+n−1 (noise drawn here)."""
        q = np.array([self._meter(k - self._delay_samples) for k in range(k0, k0 + n)])
        y = q * LPM_PER_M3S
        if self.disturbance_sd_Lpm > 0.0:
            y = y + self._disturbances(n)
        if self._clean is not None:
            self._clean.append(y.copy())
        if self.noise_sd_Lpm > 0.0:
            y = y + self._rng.normal(0.0, self.noise_sd_Lpm, size=n)
        counts = to_counts(y, FLOW_COUNTS)
        return (from_counts(counts, FLOW_COUNTS) if self.quantisation else y), counts

    def _disturbances(self, n: int) -> FloatArray:
        """The next ``n`` samples of the AR(1) flow disturbance [L/min] (drawn here)."""
        phi = self._disturbance_phi
        innovations = self._rng.normal(
            0.0, self.disturbance_sd_Lpm * math.sqrt(1.0 - phi * phi), size=n
        )
        d = np.empty(n)
        last = self._disturbance
        for i in range(n):
            last = phi * last + float(innovations[i])
            d[i] = last
        self._disturbance = last
        return d

    def _scan(self, k: int, y: float) -> None:
        """The PLC's control-period scan at sample ``k`` with the flow reading ``y`` [L/min]."""
        w = self._writes
        stale = self.heartbeat_stale()
        pending = self._pending_gains(stale)
        mode = self._operator_mode(k * self.period_s)
        e = self._setpoint - y
        pi = self._pi
        if mode == AUTO:
            if self._mode == MAN:
                # bumpless: the first output is the last manual one (without the test signal)
                pi.integral = self._u_base - pi.Kc * e
            if pending is not None:
                pi.integral += (pi.Kc - pending[0]) * e  # bumpless: the P term's change absorbed
                self._set_gains(pending)
            self._u_base = pi.update(self._setpoint, y)
        else:
            if pending is not None:
                self._set_gains(pending)
            self._u_base = float(np.clip(self._manual, self.u_min, self.u_max))
        self._mode = mode
        if stale:  # the request dies with the advisor: a new one starts from 0, not from it
            w["excitation_request"] = 0.0
        self._excitation = self._applied_excitation(w["excitation_request"], stale)
        # the test signal goes after the PI (which never sees it), the sum within the drive's
        # range; nothing is added without one, so the samples are those without the feature
        self._u = self._u_base
        if self._excitation != 0.0:
            self._u = float(np.clip(self._u_base + self._excitation, self.u_min, self.u_max))

    def _pending_gains(self, stale: bool) -> tuple[float, float, float] | None:
        """The gains this scan applies, (Kc, Ti, echo), or None.

        A new ``apply`` number takes the staged gains, clamped to the PLC's limits, when the
        heartbeat is fresh and they are finite and positive (else the set is refused); a stale
        heartbeat with ``restore_on_stale`` brings the commissioning gains back (echo 0).
        """
        w = self._writes
        pending: tuple[float, float, float] | None = None
        if w["apply"] != self._apply_seen:
            self._apply_seen = w["apply"]
            kc, ti = w["staged_kc"], w["staged_ti"]
            valid = all(math.isfinite(v) and v > 0.0 for v in (kc, ti))
            if stale or not valid:
                self._refused = True
            else:
                lo, hi = GAIN_LIMITS
                pending = (
                    float(np.clip(kc, lo * self.kc0, hi * self.kc0)),
                    float(np.clip(ti, lo * self.ti0, hi * self.ti0)),
                    self._apply_seen,
                )
        if (
            pending is None
            and stale
            and self.restore_on_stale
            and (self._pi.Kc, self._pi.Ti) != (self.kc0, self.ti0)
        ):
            pending = (self.kc0, self.ti0, 0.0)
        return pending

    def _operator_mode(self, t: float) -> int:
        """The mode of this scan at PLC time ``t`` [s]; the setpoint and manual command updated.

        A setpoint profile forces AUTO and a command profile MAN; otherwise ``mode_request``
        (0 or 1, other values ignored). Non-finite requests are ignored.
        """
        w = self._writes
        if self._sp_profile is not None:
            mode, self._setpoint = AUTO, self._sp_profile.at(t)
        else:
            request = w["mode_request"]
            mode = int(request) if request in (MAN, AUTO) else self._mode
            if math.isfinite(w["setpoint_request"]):
                self._setpoint = w["setpoint_request"]
        if self._u_profile is not None:
            mode, self._manual = MAN, self._u_profile.at(t)
        elif math.isfinite(w["manual_command"]):
            self._manual = w["manual_command"]
        return mode

    def _applied_excitation(self, request: float, stale: bool) -> float:
        """The test signal applied for ``request`` [V]: clamped, 0 if not finite or stale."""
        if stale or not math.isfinite(request):
            return 0.0
        limit = self.excitation_limit_V
        applied = min(max(float(request), -limit), limit)
        return applied if applied != 0.0 else 0.0  # no −0.0

    def _set_gains(self, gains: tuple[float, float, float]) -> None:
        self._pi.Kc, self._pi.Ti, self._echo = gains
        self._refused = False

    def _start_span(self, k0: int) -> None:
        """At a scan: read, control, then integrate the plant over the next control period."""
        n = self.n_control
        self._span_k0 = k0
        y0, c0 = self._readings(k0, 1)  # the reading the PI acts on
        self._scan(k0, float(y0[0]))
        times = (k0 + np.arange(n + 1, dtype=np.float64)) * self.plant_period_s
        T = float(self._temperature.at(times[0] + 0.5 * n * self.plant_period_s))
        if abs(T - self._coefficients.T_fuel) >= TEMPERATURE_RESOLUTION_K:
            self._coefficients = plant_coefficients(self.config, T)
        c = self._coefficients
        states = integrate_held(self._x, times, self._u, c)
        self._x = states[-1]
        self._push_history(states[1:, measured_state(c)])
        y_rest, c_rest = self._readings(k0 + 1, n - 1)
        self._span_y = np.concatenate((y0, y_rest))
        self._span_counts = np.concatenate((c0, c_rest))
        self._span_T = np.asarray(self._temperature.at(times[:-1]), dtype=float) * np.ones(n)

    def _push_history(self, values: FloatArray) -> None:
        """Append the meter states of the next samples, dropping the oldest."""
        m = values.size
        self._history = np.concatenate((self._history[m:], values))
        self._history_first_k += m

    def _take_sample(self, k: int) -> int:
        """Write the record of sample ``k`` into the ring; its slot."""
        seq = (self._seq0 + k) % SEQ_MODULUS
        slot = seq % self.ring_size
        y = self._span_y[k - self._span_k0]
        self.ring[slot] = (seq, self._u, y, self._setpoint, self._excitation)
        return slot


def _control_steps(period_s: float, control_period_s: float) -> int:
    """Samples per control period, n = control_period_s/period_s: a whole number ≥ 1."""
    if not (math.isfinite(period_s) and period_s > 0.0):
        raise ConfigError(f"period_s must be positive, got {period_s!r}")
    n_control = round(control_period_s / period_s)
    if n_control < 1 or abs(n_control * period_s - control_period_s) > 1e-9 * control_period_s:
        raise ConfigError(
            f"control_period_s ({control_period_s:g} s) must be a whole multiple of "
            f"period_s ({period_s:g} s)"
        )
    return n_control


def _check_ring_heartbeat_clock(
    ring_size: int, heartbeat_timeout_s: float, clock_slow: float
) -> None:
    """Refuse a ring size outside 2…MAX_RING_SIZE, a heartbeat timeout ≤ 0, a clock ≥ 50 % off."""
    if not 2 <= ring_size <= MAX_RING_SIZE:
        raise ConfigError(f"ring_size must be 2…{MAX_RING_SIZE}, got {ring_size}")
    if not (math.isfinite(heartbeat_timeout_s) and heartbeat_timeout_s > 0.0):
        raise ConfigError("heartbeat_timeout_s must be positive")
    if not (math.isfinite(clock_slow) and abs(clock_slow) < MAX_CLOCK_SLOW):
        raise ConfigError(
            f"clock_slow must be within (−{MAX_CLOCK_SLOW:g}, {MAX_CLOCK_SLOW:g}), "
            f"got {clock_slow!r}"
        )
