"""What ``fuelid plant info`` reports: a plant's operating point and linearised model.

The operating point at one command and fuel temperature, the equivalent model of the family
K·e^(−τs)/((T·s+1)(T_f·s+1)) it reduces to, and the full linear model's transfer function, as a
result object whose :meth:`PlantInfo.to_json` is the documented JSON (docs/reference/json.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fuelid.plant import EquivalentModel, LinearPlant, PlantConfig, linearise
from fuelid.units import LPM_PER_M3S, PA_PER_MPA, kelvin_to_celsius

PLANT_INFO_UNITS = {
    "u": "V",
    "fuel_temperature": "degC",
    "flow": "L/min",
    "pump_pressure": "MPa",
    "nozzle_pressure": "MPa",
    "speed": "rpm",
    "torque": "N*m",
    "frequency": "Hz",
    "leakage": "L/min",
    "reynolds": "1",
    "K": "(L/min)/V",
    "T": "s",
    "T2": "s",
    "T_f": "s",
    "delay": "s",
    "settling_time": "s",
    "model_settling_time": "s",
    "reduction_rms": "fraction of K",
}
"""Units of the numbers in :meth:`PlantInfo.to_json`."""


@dataclass(frozen=True)
class PlantInfo:
    """A plant linearised at one command and fuel temperature, with its equivalent model."""

    config: PlantConfig
    T_fuel: float
    """Fuel temperature [K]."""
    u: float
    """Command [V]."""
    linear: LinearPlant
    equivalent: EquivalentModel

    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``fuelid plant info --json`` (without ``config`` and provenance)."""
        op = self.linear.operating_point
        model = self.equivalent.model
        tf = self.linear.to_control()
        return {
            "plant": self.config.name,
            "fuel": self.config.fuel.name,
            "fuel_temperature": kelvin_to_celsius(self.T_fuel),
            "u": self.u,
            "operating_point": {
                "flow": op.q * LPM_PER_M3S,
                "pump_pressure": op.p_pump / PA_PER_MPA,
                "nozzle_pressure": op.p_nozzle / PA_PER_MPA,
                "speed": op.speed_rpm,
                "torque": op.torque,
                "frequency": op.f,
                "leakage": op.q_leak * LPM_PER_M3S,
                "reynolds": op.reynolds,
                # also here, where identify writes them and tune --model reads them first; the
                # top-level keys stay (documented keys keep their meaning; issue 37). Last, so
                # that the object still starts with the flow, as the docs' example shows it
                "u": self.u,
                "fuel_temperature": kelvin_to_celsius(self.T_fuel),
            },
            "model": {
                **model.to_json(),
                "settling_time": self.equivalent.settling_time,
                "model_settling_time": self.equivalent.model_settling_time,
                "reduction_rms": self.equivalent.fit_rms,
            },
            "linear_model": {
                "num": [float(v) for v in tf.num[0][0]],
                "den": [float(v) for v in tf.den[0][0]],
                "delay": self.linear.delay,
                "poles": sorted(
                    ([float(p.real), float(p.imag)] for p in tf.poles()), key=lambda p: -p[0]
                ),
            },
            "units": PLANT_INFO_UNITS,
        }


def plant_info(config: PlantConfig, T_fuel: float, u: float | None = None) -> PlantInfo:
    """Linearise ``config`` at command ``u`` [V] (default mid-range) and fuel temperature [K].

    Examples
    --------
    >>> from fuelid.plant import load_plant_config
    >>> info = plant_info(load_plant_config(), 293.15, 1.25)
    >>> info.to_json()["fuel_temperature"], info.equivalent.model.K > 0
    (20.0, True)
    >>> {k: info.to_json()["operating_point"][k] for k in ("u", "fuel_temperature")}
    {'u': 1.25, 'fuel_temperature': 20.0}
    """
    command = 0.5 * (config.vfd.u_min_V + config.vfd.u_max_V) if u is None else u
    linear = linearise(config, command, T_fuel)
    return PlantInfo(
        config=config, T_fuel=T_fuel, u=command, linear=linear, equivalent=linear.equivalent_model()
    )
