"""Helpers shared by the online service's tests.

A site for a virtual PLC, its history, an approved proposal put straight into the store (what
``fuelid online approve`` leaves).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from fuelid.online import ServiceSite
from fuelid.plc import site_identity
from fuelid.plc.virtual import VirtualPlcThread
from fuelid.store import OnlineHistory, SQLiteStore, open_store


def online_site(
    virtual: VirtualPlcThread, store: Path, online: str, *, plant: str | None = None
) -> ServiceSite:
    """The virtual PLC's site file with the store, an ``[online]`` table and ``[site] plant``."""
    text = virtual.site_text(store_url=f"sqlite:///{store}", plant=plant)
    return ServiceSite.model_validate(tomllib.loads(text + "\n[online]\n" + online))


def open_history(site: ServiceSite, store: Path) -> tuple[SQLiteStore, OnlineHistory]:
    """The site's store and its online history (close both)."""
    opened = open_store(
        f"sqlite:///{store}", period_s=site.sampling.period_s, **site_identity(site)
    )
    assert isinstance(opened, SQLiteStore)
    return opened, OnlineHistory(opened)


def approve_directly(site: ServiceSite, store: Path, kc: float, ti: float) -> int:
    """An approved proposal from the commissioning gains to (kc, ti), put into the history."""
    opened, history = open_history(site, store)
    try:
        assert site.controller is not None
        old = {"Kc": site.controller.kc, "Ti": site.controller.ti}
        new = {"Kc": kc, "Ti": ti}
        pid = history.add_proposal(
            model_id=None, old=old, new=new, detail={"reason": "test", "ideal": {"old": old,
                                                                              "new": new}}
        )  # fmt: skip
        history.set_proposal_status(pid, "approved", who="tester", why="test")
        return pid
    finally:
        history.close()
        opened.close()
