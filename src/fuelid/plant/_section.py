"""Common base of the typed, validated parameter sections of a plant configuration."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Section(BaseModel):
    """A block of a plant TOML file: unknown keys are refused, values are immutable.

    Field names carry their engineering unit as a suffix (``length_m``,
    ``displacement_cm3_per_rev``) because the TOML file is an edge of the program; each section
    converts to SI in one place.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)
