"""The identification options ``fuelid identify`` and ``fuelid report`` share, with one default.

Both commands identify the same way: no flowmeter prior unless given (by option or ``--config``),
the dead time estimated unless given, the order chosen by the information criterion. The option
types here keep their names, help and defaults the same in both, and :class:`FitOptions` gathers
their values once, to parse them into the library's settings and to record them in the JSON.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Literal

import typer

from fuelid.errors import FuelidError

if TYPE_CHECKING:
    from fuelid.identify import IdentifyOptions

OrderOption = Annotated[
    str,
    typer.Option(
        metavar="1|2|auto",
        help="Process time constants: 1, 2, or auto (two lags only when BIC prefers them and "
        "the second is longer than the sample period and excludes zero; with no meter lag given "
        "it must also be told apart from the first or be strongly preferred; a flowmeter lag "
        "that is not given is found as the second lag).",
    ),
]
DelayOption = Annotated[
    str | None,
    typer.Option(
        metavar="SECONDS|auto",
        help="Dead time: a number of seconds [s] fixes it, 'auto' estimates it (default: "
        "the flowmeter delay when given, else auto).",
        show_default=False,
    ),
]
FlowmeterTOption = Annotated[
    float | None,
    typer.Option(
        "--flowmeter-T",
        "--T-f",
        metavar="SECONDS",
        help="Flowmeter time constant T_f [s], held fixed (alias --T-f, as in fuelid tune; "
        "default: from --config, else not fixed).",
        show_default=False,
    ),
]
FlowmeterDelayOption = Annotated[
    float | None,
    typer.Option(
        "--flowmeter-delay",
        metavar="SECONDS",
        help="Flowmeter dead time [s], the model's delay unless --delay (default: from "
        "--config, else the delay is estimated).",
        show_default=False,
    ),
]
StepsOption = Annotated[
    int | None,
    typer.Option(
        "--N",
        help="step-ls: step-response length N [control periods] (default: from --config's "
        "settling time).",
        show_default=False,
    ),
]


class CovarianceChoice(enum.StrEnum):
    """How oe's parameter covariance is computed."""

    auto = "auto"
    white = "white"
    hac = "hac"


CovarianceOption = Annotated[
    CovarianceChoice,
    typer.Option(
        help="oe's standard errors: white σ²(JᵀJ)⁻¹; hac, the sandwich with the residuals' "
        "spectrum (valid when they are coloured); auto, hac whenever the residuals fail the "
        "whiteness test because of the noise (coloured where the output has settled too).",
    ),
]
DEFAULT_ORDER = "auto"
"""The order option's default in every command that identifies."""


def parse_order(text: str) -> Literal[1, 2, "auto"]:
    """``--order``'s value: 1, 2 or "auto"."""
    if text == "1":
        return 1
    if text == "2":
        return 2
    if text == "auto":
        return "auto"
    raise FuelidError(f"--order must be 1, 2 or auto, got {text!r}")


def parse_delay(text: str | None) -> float | Literal["auto"] | None:
    """``--delay``'s value: seconds, "auto", or None (not given)."""
    if text is None:
        return None
    if text == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise FuelidError(f"--delay must be 'auto' or seconds, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise FuelidError(f"--delay must be a non-negative number of seconds, got {text!r}")
    return value


def check_prior_times(flowmeter_T: float | None, flowmeter_delay: float | None) -> None:
    """Refuse a flowmeter lag or delay that is not a non-negative number of seconds."""
    for name, value in (("--flowmeter-T", flowmeter_T), ("--flowmeter-delay", flowmeter_delay)):
        if value is not None and not (math.isfinite(value) and value >= 0.0):
            raise FuelidError(f"{name} must be a non-negative number of seconds")


@dataclass(frozen=True)
class FitOptions:
    """How the model is fitted, as ``identify`` and ``report`` both take it: one home for both.

    Each field is the option as given (``--order``, ``--delay``, ``--flowmeter-T``,
    ``--flowmeter-delay``, ``--N``, ``--covariance``, ``--full-record``). The meter's prior
    times are checked on construction; the order and the delay when
    :meth:`identify_options` parses them.
    """

    order: str = DEFAULT_ORDER
    delay: str | None = None
    flowmeter_T: float | None = None
    flowmeter_delay: float | None = None
    n_steps: int | None = None
    covariance: CovarianceChoice = CovarianceChoice.auto
    full_record: bool = False

    def __post_init__(self) -> None:
        check_prior_times(self.flowmeter_T, self.flowmeter_delay)

    def identify_options(self, **settings: Any) -> IdentifyOptions:
        """The library's settings: these options parsed, with the command's own ``settings``."""
        from fuelid.identify import IdentifyOptions

        return IdentifyOptions(
            order=parse_order(self.order),
            delay=parse_delay(self.delay),
            flowmeter_T=self.flowmeter_T,
            flowmeter_delay=self.flowmeter_delay,
            N=self.n_steps,
            covariance=self.covariance.value,
            full_record=self.full_record,
            **settings,
        )

    def to_json(self) -> dict[str, Any]:
        """The options as the JSON's provenance records them (in 0.2.0's keys and order)."""
        return {
            "order": self.order,
            "delay": self.delay,
            "flowmeter_T": self.flowmeter_T,
            "flowmeter_delay": self.flowmeter_delay,
            "N": self.n_steps,
            "covariance": self.covariance.value,
            "full_record": self.full_record,
        }
