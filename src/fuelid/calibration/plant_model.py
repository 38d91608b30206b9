"""The fuel plant's mechanism model as a gray-box model of its physical parameters.

The state, the right-hand side and its state Jacobian are the plant's own
(:func:`~fuelid.plant._system.plant_rhs`, :func:`~fuelid.plant._system.plant_jacobian`, analytic);
∂f/∂θ for a physical parameter θ (a dotted plant-file name such as ``pump.leakage_Lpm_per_MPa``)
is a forward difference of the right-hand side between the plant's coefficients at θ and at
θ·(1 + 10⁻⁶), both built once per record and parameter vector, so it costs one extra right-hand
side per parameter per step. Each record carries its fuel temperature (``context``), which sets
the viscosity and density every coefficient depends on: several records at different
temperatures are what separate the viscosity-dependent parameters.

Outputs: the meter's reading [L/min] (its lagged state, read ``delay`` later) and, when logged,
the pump outlet pressure [MPa] (gauge, no delay). Each record starts at rest at its first command
(the steady state, whose derivative in θ is a difference of two steady states).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from fuelid.greybox import ParameterSpec, Record
from fuelid.plant import (
    N_STATES,
    STATE_NAMES,
    PlantCoefficients,
    PlantConfig,
    measured_state,
    plant_coefficients,
    plant_jacobian,
    plant_parameters,
    plant_rhs,
    steady_state,
    with_parameters,
)
from fuelid.plant.simulate import ATOL
from fuelid.units import LPM_PER_M3S, PA_PER_MPA

FloatArray = NDArray[np.float64]
FUEL_TEMPERATURE_KEY = "fuel_temperature_K"
"""The key of a record's context that holds its fuel temperature [K]."""
RELATIVE_STEP = 1e-6
"""Relative step of the forward difference in each physical parameter."""
NOT_CALIBRATABLE = {
    "flowmeter.delay_s": "the dead time is read off the step response (fuelid identify), "
    "not fitted here",
    "flowmeter.span_Lpm": "the meter's span scales readings, it is no dynamic parameter",
    "flowmeter.noise_std_Lpm": "the noise level is estimated from the residuals",
    "flowmeter.resolution_Lpm": "the meter's resolution is a property of its reading",
}


class PlantSystem:
    """The plant at one parameter vector and fuel temperature (an OdeSystem)."""

    def __init__(
        self,
        base: PlantCoefficients,
        perturbed: Sequence[PlantCoefficients],
        steps: FloatArray,
        with_pressure: bool,
    ) -> None:
        self.base = base
        self.perturbed = list(perturbed)
        self.steps = steps
        self.with_pressure = with_pressure
        self.n_states = N_STATES
        self.atol = ATOL
        # the meter's dead time delays the flow reading; a pressure transmitter has none here
        self.output_delay: float | FloatArray = (
            np.array([base.delay, 0.0]) if with_pressure else base.delay
        )
        self._flow_index = measured_state(base)

    def derivatives(
        self, t: float, x: FloatArray, u: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """f, the analytic ∂f/∂x and ∂f/∂θ by a forward difference in each parameter."""
        command = float(u[0])
        state = x.tolist()
        base = np.array(plant_rhs(t, state, command, self.base))
        jac_theta = np.empty((N_STATES, len(self.perturbed)))
        for j, coefficients in enumerate(self.perturbed):
            jac_theta[:, j] = (np.array(plant_rhs(t, state, command, coefficients)) - base) / (
                self.steps[j]
            )
        return base, plant_jacobian(t, x, command, self.base), jac_theta

    def state_jacobian(self, t: float, x: FloatArray, u: FloatArray) -> FloatArray:
        """The analytic ∂f/∂x."""
        return plant_jacobian(t, x, float(u[0]), self.base)

    def outputs(self, x: FloatArray, u: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Flow [L/min] (and pump pressure [MPa]); linear in the state, free of θ."""
        n_samples = len(x)
        columns = [x[:, self._flow_index] * LPM_PER_M3S]
        dy_dx = np.zeros((n_samples, 2 if self.with_pressure else 1, N_STATES))
        dy_dx[:, 0, self._flow_index] = LPM_PER_M3S
        if self.with_pressure:
            columns.append(x[:, STATE_NAMES.index("p")] / PA_PER_MPA)
            dy_dx[:, 1, STATE_NAMES.index("p")] = 1.0 / PA_PER_MPA
        y = np.column_stack(columns)
        return y, dy_dx, np.zeros((n_samples, y.shape[1], len(self.perturbed)))

    def initial_state(self, u0: FloatArray, y0: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """At rest at the first command: the steady state and its θ-derivative."""
        command = float(u0[0])
        x0 = steady_state(command, self.base).state
        jac = np.empty((N_STATES, len(self.perturbed)))
        for j, coefficients in enumerate(self.perturbed):
            jac[:, j] = (steady_state(command, coefficients).state - x0) / self.steps[j]
        return x0, jac


class PlantGreyBox:
    """A plant config with some of its parameters free (a GreyBoxModel).

    Parameters
    ----------
    config : PlantConfig
        The plant; its values are the start of the fit and the values of the parameters held.
    free : sequence of str
        Dotted plant-file names to estimate.
    with_pressure : bool
        The records' second output column is the pump outlet pressure [MPa].
    """

    def __init__(self, config: PlantConfig, free: Sequence[str], with_pressure: bool) -> None:
        registry = plant_parameters(config)
        self.config = config
        self.with_pressure = with_pressure
        self.state_names: tuple[str, ...] = STATE_NAMES
        self.output_names: tuple[str, ...] = ("flow", "pressure") if with_pressure else ("flow",)
        self.state_scale = 1.0
        self.parameters = tuple(
            ParameterSpec(
                name,
                registry[name].value,
                registry[name].lower,
                registry[name].upper,
            )
            for name in free
        )

    def coefficients(self, values: Mapping[str, float], T_fuel: float) -> PlantCoefficients:
        """The plant's coefficients with ``values`` at fuel temperature ``T_fuel`` [K]."""
        return plant_coefficients(with_parameters(self.config, values), T_fuel)

    def bind(self, values: Mapping[str, float], free: Sequence[str], record: Record) -> PlantSystem:
        """The plant at ``values`` and the record's fuel temperature."""
        T_fuel = float(record.context[FUEL_TEMPERATURE_KEY])
        base = self.coefficients(values, T_fuel)
        perturbed, steps = [], []
        for name in free:
            step = RELATIVE_STEP * max(abs(values[name]), 1e-9)
            shifted = dict(values)
            shifted[name] = values[name] + step
            perturbed.append(self.coefficients(shifted, T_fuel))
            steps.append(step)
        return PlantSystem(base, perturbed, np.array(steps), self.with_pressure)

    def steady_state_guess(self, values: Mapping[str, float], record: Record) -> FloatArray:
        """The steady state at the record's first command."""
        T_fuel = float(record.context[FUEL_TEMPERATURE_KEY])
        return steady_state(float(record.u[0, 0]), self.coefficients(values, T_fuel)).state
