"""What the estimator needs of a model: records, and the model bound to one record and θ.

A :class:`Record` is one experiment: sample times, the inputs held between samples (the PLC's
sample-and-hold), the measured outputs (NaN where a sample is missing) and a context (a fuel
temperature, say) the model may read. A :class:`OdeSystem` is the model at one parameter vector for
one record: it gives f(x, u) with its Jacobians ∂f/∂x and ∂f/∂θ, the outputs with theirs, and
optionally the initial state as a function of θ. :mod:`fuelid.greybox._sensitivity` integrates the
state and its forward sensitivities from it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError
from fuelid.greybox._parameters import ParameterSpec

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Record:
    """One experiment.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Sample times [s], strictly increasing.
    u : ndarray, shape (N, n_u)
        Inputs, each held from its sample to the next.
    y : ndarray, shape (N, n_y)
        Measured outputs; NaN marks a missing sample.
    name : str
        Shown in reports (a file name, say).
    context : mapping
        Constants of the experiment the model reads (e.g. ``{"fuel_temperature_K": 293.15}``).
    """

    t: FloatArray
    u: FloatArray
    y: FloatArray
    name: str = ""
    context: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_arrays(
        cls,
        t: Sequence[float] | FloatArray,
        u: Sequence[float] | FloatArray,
        y: Sequence[float] | FloatArray,
        name: str = "",
        context: Mapping[str, float] | None = None,
    ) -> Record:
        """Validate and shape arrays (1-D inputs/outputs become one column).

        Raises
        ------
        DataError
            On mismatched lengths, fewer than 3 samples, non-increasing or non-finite times, or
            non-finite inputs.
        """
        t_arr = np.asarray(t, dtype=float).ravel()
        u_arr = np.asarray(u, dtype=float)
        y_arr = np.asarray(y, dtype=float)
        u_arr = u_arr.reshape(len(u_arr), -1) if u_arr.ndim < 2 else u_arr
        y_arr = y_arr.reshape(len(y_arr), -1) if y_arr.ndim < 2 else y_arr
        return cls(t_arr, u_arr, y_arr, name, dict(context or {})).validate()

    def validate(self) -> Record:
        """Check the record can be fitted (what :meth:`from_arrays` checks); return it.

        Raises
        ------
        DataError
            On arrays of the wrong shape, mismatched lengths, fewer than 3 samples,
            non-increasing or non-finite times, non-finite inputs or no finite output.
        """
        label = f"record {self.name}" if self.name else "record"
        t_arr, u_arr, y_arr = self.t, self.u, self.y
        if t_arr.ndim != 1 or u_arr.ndim != 2 or y_arr.ndim != 2:
            raise DataError(
                f"{label}: t must be 1-D and u, y 2-D (samples × columns); got "
                f"{t_arr.ndim}-D, {u_arr.ndim}-D, {y_arr.ndim}-D (use Record.from_arrays)"
            )
        if not (len(t_arr) == len(u_arr) == len(y_arr)):
            raise DataError(
                f"{label}: {len(t_arr)} times, {len(u_arr)} inputs and {len(y_arr)} outputs "
                "differ in length"
            )
        if len(t_arr) < 3:
            raise DataError(f"{label}: {len(t_arr)} samples; at least 3 are needed")
        if not np.all(np.isfinite(t_arr)) or np.any(np.diff(t_arr) <= 0.0):
            raise DataError(f"{label}: times must be finite and strictly increasing")
        if not np.all(np.isfinite(u_arr)):
            raise DataError(f"{label}: inputs hold NaN or infinite values")
        if not np.any(np.isfinite(y_arr)):
            raise DataError(f"{label}: no finite output sample")
        return self

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return len(self.t)

    def head(self, n: int) -> Record:
        """The first ``n`` samples as a record of their own."""
        return Record(self.t[:n], self.u[:n], self.y[:n], self.name, self.context)


class OdeSystem(Protocol):
    """A model at one parameter vector θ (the free parameters, natural units) for one record."""

    n_states: int
    atol: FloatArray
    """Absolute integration tolerance per state."""
    output_delay: float | FloatArray
    """Outputs at t are read from the state at t − output_delay [s] (a transport delay); one
    delay for all outputs, or one per output."""

    def derivatives(
        self, t: float, x: FloatArray, u: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """f(t, x, u), ∂f/∂x (n × n) and ∂f/∂θ (n × p)."""
        ...

    def state_jacobian(self, t: float, x: FloatArray, u: FloatArray) -> FloatArray:
        """∂f/∂x (n × n) alone (the stiff solver's Newton matrix)."""
        ...

    def outputs(self, x: FloatArray, u: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Outputs and their derivatives at every sample.

        For states x (N × n) and inputs u (N × n_u): y (N × n_y), ∂y/∂x (N × n_y × n) and
        ∂y/∂θ (N × n_y × p).
        """
        ...

    def initial_state(self, u0: FloatArray, y0: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """x0 and ∂x0/∂θ (n × p) when the model fixes the initial state, else None (estimated)."""
        ...


class GreyBoxModel(Protocol):
    """A parametrised ODE model the estimator can fit."""

    state_names: tuple[str, ...]
    output_names: tuple[str, ...]
    parameters: tuple[ParameterSpec, ...]

    def bind(self, values: Mapping[str, float], free: Sequence[str], record: Record) -> OdeSystem:
        """The system at the parameter values ``values`` for ``record``; θ is ``free`` in order."""
        ...

    def steady_state_guess(self, values: Mapping[str, float], record: Record) -> FloatArray:
        """A start for an estimated initial state (e.g. the steady state at the first input)."""
        ...
