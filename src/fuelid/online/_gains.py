"""The PI gains the online service holds, proposes and writes: :class:`Gains`, a PISettings.

A :class:`Gains` *is* the tuning layer's :class:`~fuelid.tuning._rules.PISettings` (ideal form,
Kc [V per L/min], Ti [s]), built from its two numbers; it adds no conversion of its own. The PLC
block's form and units, and the one conversion to and from them, are
:mod:`fuelid.tuning._block` (:class:`~fuelid.tuning._block.BlockForm`,
:meth:`~fuelid.tuning._rules.PISettings.to_block`,
:meth:`~fuelid.tuning._rules.PISettings.from_block`, :func:`~fuelid.tuning._block.block_units`).
"""

from __future__ import annotations

from fuelid.tuning import PISettings, ReducedModel

HELD = "online"
"""The ``rule`` of a :class:`Gains` built from its two numbers: gains the service holds (read
from the PLC, stored, proposed), whose own rule is not part of them."""


class Gains(PISettings):
    """Ideal-form PI gains C(s) = Kc·(1 + 1/(Ti·s)) in engineering units, as the service keeps them.

    A :class:`~fuelid.tuning._rules.PISettings` built from its two numbers (``Gains(Kc, Ti)``),
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
        As :class:`~fuelid.tuning._rules.PISettings` (keywords).

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

    def to_json(self) -> dict[str, float]:
        """``{"Kc": ..., "Ti": ...}`` [V per L/min, s]: what the store holds.

        Examples
        --------
        >>> Gains(0.05, 2.0).to_json()
        {'Kc': 0.05, 'Ti': 2.0}
        """
        return {"Kc": float(self.Kc), "Ti": float(self.Ti)}


__all__ = ["HELD", "Gains"]
