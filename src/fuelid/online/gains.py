"""The PI gains the online service holds, proposes and writes: :class:`Gains`, a PISettings.

A :class:`Gains` *is* the tuning layer's :class:`~fuelid.tuning.rules.PISettings` (ideal form,
Kc [V per L/min], Ti [s]), built from its two numbers; it adds no conversion of its own. The PLC
block's form and units, and the one conversion to and from them, are
:mod:`fuelid.tuning.block` (:class:`~fuelid.tuning.block.BlockForm`,
:meth:`~fuelid.tuning.rules.PISettings.to_block`,
:meth:`~fuelid.tuning.rules.PISettings.from_block`, :func:`~fuelid.tuning.block.block_units`).

Moved in fuelid 0.2.0, kept here for one minor release with a DeprecationWarning on import:
``controller_to_ideal`` (now :func:`fuelid.tuning.block.from_block`), ``ideal_to_controller``
(:func:`fuelid.tuning.block.to_block`), ``gain_units`` (:func:`fuelid.tuning.block.block_units`)
and ``SECONDS_PER_MINUTE`` (:data:`fuelid.tuning.block.SECONDS_PER_MINUTE`).
"""

from __future__ import annotations

import warnings
from typing import Any

from fuelid._deprecated import warn_renamed
from fuelid.tuning.block import SECONDS_PER_MINUTE as _SECONDS_PER_MINUTE
from fuelid.tuning.block import BlockForm, block_units, from_block, to_block
from fuelid.tuning.rules import PISettings, ReducedModel

HELD = "online"
"""The ``rule`` of a :class:`Gains` built from its two numbers: gains the service holds (read
from the PLC, stored, proposed), whose own rule is not part of them."""


class Gains(PISettings):
    """Ideal-form PI gains C(s) = Kc·(1 + 1/(Ti·s)) in engineering units, as the service keeps them.

    A :class:`~fuelid.tuning.rules.PISettings` built from its two numbers (``Gains(Kc, Ti)``),
    stored as ``{"Kc", "Ti"}`` (:meth:`to_json`). Its ``rule`` is :data:`HELD` and its
    ``control_period`` 0 unless given: give the PLC's period before using one as a sampled
    controller.

    Parameters
    ----------
    Kc : float
        Proportional gain [V per L/min], > 0.
    Ti : float
        Integral (reset) time [s], > 0.
    rule, control_period, tuning_parameter, reduced
        As :class:`~fuelid.tuning.rules.PISettings` (keywords).

    Examples
    --------
    >>> g = Gains(0.05, 2.0)
    >>> isinstance(g, PISettings), g.to_json()
    (True, {'Kc': 0.05, 'Ti': 2.0})
    """

    def __init__(
        self,
        Kc: float,
        Ti: float,
        *,
        rule: str = HELD,
        control_period: float = 0.0,
        tuning_parameter: float | None = None,
        reduced: ReducedModel | None = None,
    ) -> None:
        super().__init__(
            rule=rule,
            Kc=Kc,
            Ti=Ti,
            control_period=control_period,
            tuning_parameter=tuning_parameter,
            reduced=reduced,
        )

    def to_dict(self, *args: Any, **kwargs: Any) -> dict[str, float]:
        """Deprecated name of :meth:`to_json` (fuelid 0.2.0)."""
        warn_renamed(self, "to_dict")
        return self.to_json(*args, **kwargs)

    def to_json(self) -> dict[str, float]:
        """``{"Kc": ..., "Ti": ...}`` [V per L/min, s]: what the store holds.

        Examples
        --------
        >>> Gains(0.05, 2.0).to_json()
        {'Kc': 0.05, 'Ti': 2.0}
        """
        return {"Kc": float(self.Kc), "Ti": float(self.Ti)}


# --- the names that moved to fuelid.tuning.block (fuelid 0.2.0) -----------------------------------


def _controller_to_ideal(kc: float, ti: float, controller: Any) -> Gains:
    """Deprecated: ``Gains(*from_block(kc, ti, BlockForm.of(controller)))``."""
    return Gains(*from_block(kc, ti, BlockForm.of(controller)))


def _ideal_to_controller(gains: PISettings, controller: Any) -> tuple[float, float]:
    """Deprecated: ``gains.to_block(BlockForm.of(controller))``."""
    return to_block(gains.Kc, gains.Ti, BlockForm.of(controller))


def _gain_units(controller: Any) -> dict[str, str] | None:
    """Deprecated: ``block_units(BlockForm.of(controller))`` (None for None)."""
    return None if controller is None else block_units(BlockForm.of(controller))


MOVED: dict[str, tuple[Any, str]] = {
    "controller_to_ideal": (
        _controller_to_ideal,
        "fuelid.tuning.block.from_block (or PISettings.from_block)",
    ),
    "ideal_to_controller": (
        _ideal_to_controller,
        "fuelid.tuning.block.to_block (or PISettings.to_block)",
    ),
    "gain_units": (_gain_units, "fuelid.tuning.block.block_units"),
    "SECONDS_PER_MINUTE": (_SECONDS_PER_MINUTE, "fuelid.tuning.block.SECONDS_PER_MINUTE"),
}
"""Old name → (what it still gives, where it went)."""


def moved_name(
    module: str, name: str, only: tuple[str, ...] | None = None, stacklevel: int = 3
) -> Any:
    """The moved name ``name`` of ``module``, with its DeprecationWarning.

    For a module's ``__getattr__`` (PEP 562): the warning is attributed to the line that imports
    or reads the name (``stacklevel`` 3: this function, the module's ``__getattr__``, its caller).
    ``only``: the names of :data:`MOVED` that ``module`` had (None: all of them).

    Raises
    ------
    AttributeError
        When ``name`` is not one of :data:`MOVED`.
    """
    if name not in MOVED or (only is not None and name not in only):
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    value, new = MOVED[name]
    warnings.warn(
        f"{module}.{name} moved to {new} in fuelid 0.2.0; use that instead "
        f"(the old name will be removed in a future release)",
        DeprecationWarning,
        stacklevel=stacklevel,
    )
    return value


def __getattr__(name: str) -> Any:
    return moved_name(__name__, name)


__all__ = ["HELD", "Gains"]
