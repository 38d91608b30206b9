"""Retention with an archive: archive the finished days, then prune only what is archived.

What ``fuelid record`` and the online service run at their hourly housekeeping when the site
file has an ``[archive]`` table (:func:`keep_store`); without one they prune as before.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from fuelid.archive._writer import ArchiveReport, archive_store
from fuelid.errors import FuelidError
from fuelid.store import PruneResult, SampleStore, SQLiteStore, StoreError

__all__ = ["Housekeeping", "archiver", "keep_store"]


@dataclass(frozen=True)
class Housekeeping:
    """One round of :func:`keep_store`.

    The archive's report (None when not archived), the retention's result, and why archiving
    failed (None when it did not).
    """

    archive: ArchiveReport | None
    prune: PruneResult
    archive_error: str | None


def keep_store(
    store: SQLiteStore,
    retention_days: float,
    thin_to_s: float | None,
    *,
    now: float | None = None,
    archive_dir: str | None = None,
    auto: bool = True,
) -> Housekeeping:
    """Archive the finished days (with ``archive_dir`` and ``auto``), then apply retention.

    With ``archive_dir`` retention deletes or thins only the samples of archived days (so a
    failed archive loses nothing: the error is returned, retention still runs on what was
    archived before); without it, retention as :meth:`SQLiteStore.prune` always did.

    Parameters
    ----------
    store : SQLiteStore
        The store, open for writing.
    retention_days, thin_to_s : float
        ``[store] retention_days`` [d] and ``thin_to_s`` [s] (None: delete).
    now : float, optional
        The retention's reference time [s UTC] (the wall clock by default).
    archive_dir : str, optional
        ``[archive] dir``.
    auto : bool
        ``[archive] auto``: archive here; False leaves it to ``fuelid archive`` (a cron job).

    Raises
    ------
    StoreError
        Retention itself failed.
    """
    report, error = None, None
    if archive_dir is not None and auto:
        try:
            report = archive_store(store, archive_dir)
        except FuelidError as failure:  # retention below is safe without it: say it, go on
            error = " ".join(str(failure).split())
    result = store.prune(retention_days, thin_to_s, now=now, archived_only=archive_dir is not None)
    return Housekeeping(report, result, error)


def archiver(root: str) -> Callable[[SampleStore], ArchiveReport]:
    """The archiving step ``fuelid record`` runs before its retention (``[archive] dir``).

    Examples
    --------
    >>> callable(archiver("/srv/fuelid/archive"))
    True
    """

    def archive(store: SampleStore) -> ArchiveReport:
        if not isinstance(store, SQLiteStore):
            raise StoreError(f"{store.path}: only an SQLite store can be archived")
        return archive_store(store, root)

    return archive
