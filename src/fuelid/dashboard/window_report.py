"""The HTML report of one window, as ``fuelid report`` writes it for a log.

The window's samples are analysed as a log (both identifications, the tuning, the check over
fuel temperature) and rendered with the report's template, the figures embedded. The plant file
is the one the service ran with (its path and SHA-256 are in the service's record), when it is
still there with the same hash; otherwise the built-in reference plant stands in, and the report
says so, as ``fuelid report`` does without ``--plant``. The last few reports are kept in memory
(an analysis takes seconds).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fuelid.dashboard.source import LoopReader
from fuelid.errors import FuelidError

if TYPE_CHECKING:
    from fuelid.workflow import AnalysisSettings

__all__ = ["CACHED_REPORTS", "window_report_html"]

CACHED_REPORTS = 8
"""Reports kept in memory."""

_cache: OrderedDict[tuple[str, str, int], str] = OrderedDict()
_lock = threading.Lock()


def _error_page(title: str, reason: str) -> str:
    import html

    return (
        "<!doctype html><html><head><meta charset='utf-8'><title>report</title></head><body>"
        f"<h1>{html.escape(title)}</h1><p>{html.escape(reason)}</p></body></html>"
    )


def _plant(loop: LoopReader) -> Any:
    """The service's plant file when it is still there unchanged, else the reference plant."""
    from fuelid.online.liveness import plant_hash
    from fuelid.plant import load_plant_config
    from fuelid.workflow import PlantSource

    settings = (loop.status().get("service") or {}).get("settings") or {}
    path, digest = settings.get("plant_file"), settings.get("plant_hash")
    if path and digest and Path(path).is_file() and plant_hash(path) == digest:
        return PlantSource(load_plant_config(path), path=str(path))
    return PlantSource(load_plant_config(None))


def _settings(loop: LoopReader) -> AnalysisSettings:
    """The report's settings from the service's: its rule, PI period and the block's spans.

    The site file's control period and spans are the user's facts (none is assumed); a service
    that wrote no settings leaves the period unknown, and the page then says why it has none.
    """
    from fuelid.workflow import AnalysisSettings

    settings = (loop.status().get("service") or {}).get("settings") or {}
    sampling = settings.get("sampling") or {}
    controller = settings.get("controller") or {}
    rule = settings.get("rule")
    return AnalysisSettings(
        accept_signals=True,
        rule=rule if isinstance(rule, str) else AnalysisSettings.rule,
        control_period=sampling.get("control_period_s"),
        control_period_basis="site file",
        site_spans=(controller.get("u_span_V"), controller.get("y_span_Lpm")),
    )


def window_report_html(loop: LoopReader, row: dict[str, Any]) -> str:
    """The report page of the window ``row`` of ``loop`` (an explanation page when it fails)."""
    from fuelid.htmlreport import ReportFigure, _png, render_report, report_figures
    from fuelid.store.base import iodata_from_samples
    from fuelid.workflow import analyse_log

    key = (loop.loop_id, str(loop.identity().get("store_uuid")), int(row["id"]))
    with _lock:
        if key in _cache:
            _cache.move_to_end(key)
            return _cache[key]
    samples = loop.samples(float(row["t_from"]), float(row["t_to"]))
    title = f"Window {row['id']} of loop {loop.loop_id}"
    try:
        data = iodata_from_samples(samples, loop.identity().get("period_s"), source=title)
        analysis = analyse_log(data, _plant(loop), _settings(loop))
        drawn = report_figures(analysis)
        figures = [ReportFigure(k, caption, _png(fig)) for k, (fig, caption) in drawn.items()]
        html = render_report(analysis, figures)
    except FuelidError as error:
        html = _error_page(title, f"the report could not be made: {error}")
    with _lock:
        _cache[key] = html
        while len(_cache) > CACHED_REPORTS:
            _cache.popitem(last=False)
    return html
