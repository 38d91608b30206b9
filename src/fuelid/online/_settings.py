"""The online service's settings: the site file's ``[online]`` table, and the site it runs on.

:class:`Online` is the ``[online]`` table (the schedule, the gates, the proposal rules, the
write-back mode), read by the service, the fleet re-identification and the dashboard's window
page. :class:`ServiceSite` is the site file as the service reads it: the PLC side's
:class:`~fuelid.plc.site.SiteConfig` (which passes ``[online]`` over: the PLC layer does not
depend on the service's settings) with ``online``, and the check that a write-back has its write
side; :func:`load_service_site` reads one, and is what the commands load a site file with.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from fuelid.plc.site import Pair, SiteConfig, load_site_as

__all__ = ["Online", "ServiceSite", "load_service_site"]


class Online(BaseModel):
    """``[online]``: the online service's schedule, gates and proposal rules (issue 15).

    Every threshold has its default here; docs/reference/site-file.md says what each does.
    Unknown keys are refused (a typo must not pass); immutable.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    identify_every_s: float = Field(
        300.0, ge=30.0, description="identify every this much data time [s] (at least 30)"
    )
    window_s: float = Field(600.0, ge=60.0, description="rolling window identified [s]")
    write_back: Literal["off", "approve", "auto"] = Field(
        "off", description="off: propose only; approve: write approved proposals; auto: write"
    )
    rule: Literal["simc", "isimc", "lambda", "amigo"] = Field("simc", description="PI rule")
    ms_target: float = Field(1.7, gt=1.0, le=3.0, description="robustness target Ms")
    gain_bounds: Pair = Field(
        default_factory=lambda: [0.5, 2.0],
        description="hard bounds of Kc and Ti as multiples of the commissioning gains",
    )
    agree_windows: int = Field(2, ge=1, le=10, description="accepted windows that must agree")
    hysteresis: float = Field(0.1, ge=0.0, le=1.0, description="smallest relative gain change")
    move_fraction: float = Field(
        0.5, gt=0.0, le=1.0, description="share of the way toward the target gains per proposal"
    )
    max_limit_share: float = Field(
        0.05, ge=0.0, le=1.0, description="gate: share of the window with u at a limit"
    )
    max_bad_share: float = Field(
        0.05, ge=0.0, le=1.0, description="gate: share of lost or flagged samples"
    )
    max_rel_stderr_K: float = Field(0.05, gt=0.0, description="gate: relative std. error of K")
    max_rel_stderr_T: float = Field(0.2, gt=0.0, description="gate: relative std. error of T")
    min_fit_percent: float = Field(80.0, ge=0.0, le=100.0, description="gate: validation fit")
    max_residual_acf: float = Field(
        0.7, gt=0.0, lt=1.0, description="gate: largest |residual autocorrelation| over the lags"
    )
    plant_ratio_event: Pair = Field(
        default_factory=lambda: [0.5, 2.0],
        description="an identified K outside these multiples of the plant's K raises an event",
    )
    revert_iae_factor: float = Field(
        1.5, gt=1.0, description="revert when the IAE per setpoint change worsens this much"
    )
    echo_timeout_s: float = Field(5.0, gt=0.0, description="wait this long for the PLC's echo")

    @model_validator(mode="after")
    def _schedule_covers_the_data(self) -> Online:
        if self.identify_every_s > self.window_s:
            raise ValueError(
                f"identify_every_s ({self.identify_every_s:g} s) is longer than window_s "
                f"({self.window_s:g} s): the data between windows would never be analysed"
            )
        return self

    @model_validator(mode="after")
    def _bounds(self) -> Online:
        for key in ("gain_bounds", "plant_ratio_event"):
            low, high = getattr(self, key)
            if not 0.0 < low <= 1.0 <= high:
                raise ValueError(f"{key}: [low, high] with 0 < low <= 1 <= high, got {low}, {high}")
        return self


class ServiceSite(SiteConfig):
    """A whole site file as the online service reads it: :class:`SiteConfig` and ``[online]``.

    Beside :class:`SiteConfig`'s checks: ``[online] write_back`` other than ``"off"`` needs the
    write side (``write.kc``, ``write.ti``, ``write.apply``, ``write.echo``) and a
    ``[controller]`` table.
    """

    online: Online = Field(default_factory=Online)

    @model_validator(mode="after")
    def _write_side_of_write_back(self) -> ServiceSite:
        if self.online.write_back != "off":
            needed = [role for role in ("kc", "ti", "apply", "echo") if role not in self.write]
            if needed:
                raise ValueError(
                    f"online.write_back = {self.online.write_back!r} needs the write side: "
                    f"write.{needed[0]} is missing (staged kc, ti, apply and its echo)"
                )
            if self.controller is None:
                raise ValueError(
                    f"online.write_back = {self.online.write_back!r} needs a [controller] table "
                    "(the form and units the PLC reads its gains in)"
                )
        return self


def load_service_site(path: str | Path) -> ServiceSite:
    """Read and validate a site file, ``[online]`` included.

    Raises
    ------
    ConfigError
        One line: the file, the key and the reason.
    """
    return load_site_as(path, ServiceSite)
