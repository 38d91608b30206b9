"""The site file's tables for many loops (issue 26): ``[archive]`` and ``[central]``.

Kept beside :mod:`fuelid.plc.site`, which reads the whole file and holds them as
``SiteConfig.archive`` and ``SiteConfig.central`` (None when the table is absent).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["Archive", "Central"]


class _Table(BaseModel):
    """A table of the site file: unknown keys refused, immutable (as in fuelid.plc.site)."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class Archive(_Table):
    """``[archive]``: the raw archive, hive-partitioned Parquet (issue 26, ``fuelid archive``).

    With it, the store's retention deletes only samples of days archived and read back; the
    service archives every finished UTC day at its hourly housekeeping when ``auto``.
    """

    dir: str = Field(min_length=1, description="the archive's folder (local or a mounted share)")
    auto: bool = Field(True, description="the online service archives each finished day itself")


class Central(_Table):
    """``[central]``: the PostgreSQL database every loop's service sends to (issue 26).

    The URL names the server, database and user, never a password: libpq takes it from the
    environment (``PGPASSWORD``), a password file (``~/.pgpass``, ``PGPASSFILE``) or a service
    file (``postgresql:///?service=NAME``); TLS by ``sslmode`` in the URL.
    """

    url: str = Field(pattern=r"^postgres(ql)?://", description="postgresql://user@host/db?…")
    send_every_s: float = Field(5.0, gt=0.0, le=3600.0, description="send the outbox this often")
    batch_rows: int = Field(5000, ge=1, le=1_000_000, description="rows per send at most")
    # no retention here: the centre's owner drops old months (`fuelid central retention`), so
    # one site's clock or setting never decides for the fleet

    @model_validator(mode="before")
    @classmethod
    def _no_retention(cls, data: object) -> object:
        if isinstance(data, dict) and "retention_months" in data:
            raise ValueError(
                "central.retention_months: the centre's owner keeps the retention "
                "(`fuelid central retention --url URL --months N`, a cron job); remove it here"
            )
        return data

    @model_validator(mode="after")
    def _no_password(self) -> Central:
        from urllib.parse import parse_qs, urlsplit

        parts = urlsplit(self.url)
        if parts.password is not None or "password" in parse_qs(parts.query):
            raise ValueError(
                "central.url: no password in the site file; give it by PGPASSWORD, ~/.pgpass "
                "or a libpq service file"
            )
        return self
