"""The HTML report of one window, as ``fuelid report`` writes it for a log.

The window's samples are analysed as a log (both identifications, the tuning, the check over
fuel temperature) and rendered with the report's template, the figures embedded. The plant file
is the one the service ran with (its path and SHA-256 are in the service's record), when it is
still there with the same hash; otherwise the built-in reference plant stands in, and the report
says so, as ``fuelid report`` does without ``--plant``. The last few analyses are kept in memory
(an analysis takes seconds); the page is rendered afresh each time.

When the online service filed a proposal from this window (the proposal's ``model_id`` is the
window's), the page's notices say so, with the proposal's gains in the same ideal form as the
page's "PI gains to enter in the PLC", and, when the two differ by more than
:data:`SAME_GAINS` (relative), why: another rule or PLC period, the service's own fit of the
window, the weighted mean of the agreeing windows' models, the gain bounds, the partial move
(``move_fraction``), the detuning for Ms (:func:`proposal_notice`, from what the proposal
recorded: :func:`fuelid.online.report.decision_json`).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fuelid.dashboard.source import LoopReader
from fuelid.errors import FuelidError
from fuelid.workflow.analysis import LogAnalysis

if TYPE_CHECKING:
    from fuelid.htmlreport import ReportFigure
    from fuelid.model import ProcessModel
    from fuelid.tuning import PISettings
    from fuelid.workflow import AnalysisSettings

__all__ = ["CACHED_REPORTS", "SAME_GAINS", "proposal_notice", "window_report_html"]

CACHED_REPORTS = 8
"""Analyses kept in memory."""
SAME_GAINS = 0.01
"""Gains within this of each other (relative, Kc and Ti each) are the same gains [-]."""

_cache: OrderedDict[tuple[str, str, int], tuple[LogAnalysis, list[ReportFigure]] | str] = (
    OrderedDict()
)
_lock = threading.Lock()


@dataclass
class _WindowAnalysis(LogAnalysis):
    """A window's analysis whose notices end with what the online service made of the window."""

    online_notices: list[str] = field(default_factory=list)

    @property
    def notices(self) -> list[str]:
        """The analysis' notices, then the online proposals from the window."""
        return [*super().notices, *self.online_notices]


def _with_notices(analysis: LogAnalysis, lines: Sequence[str]) -> LogAnalysis:
    if not lines:
        return analysis
    kept = {f.name: getattr(analysis, f.name) for f in fields(LogAnalysis) if f.init}
    return _WindowAnalysis(**kept, online_notices=list(lines))


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


def _analysed(
    loop: LoopReader, row: dict[str, Any]
) -> tuple[LogAnalysis, list[ReportFigure]] | str:
    """The window's analysis and figures (kept in memory), or its explanation page."""
    from fuelid.htmlreport import ReportFigure, _png, report_figures
    from fuelid.store.base import iodata_from_samples
    from fuelid.workflow import analyse_log

    key = (loop.loop_id, str(loop.identity().get("store_uuid")), int(row["id"]))
    with _lock:
        if key in _cache:
            _cache.move_to_end(key)
            return _cache[key]
    samples = loop.samples(float(row["t_from"]), float(row["t_to"]))
    title = f"Window {row['id']} of loop {loop.loop_id}"
    done: tuple[LogAnalysis, list[ReportFigure]] | str
    try:
        data = iodata_from_samples(samples, loop.identity().get("period_s"), source=title)
        analysis = analyse_log(data, _plant(loop), _settings(loop))
        drawn = report_figures(analysis)
        figures = [ReportFigure(k, caption, _png(fig)) for k, (fig, caption) in drawn.items()]
        done = (analysis, figures)
    except FuelidError as error:
        done = _error_page(title, f"the report could not be made: {error}")
    with _lock:
        _cache[key] = done
        while len(_cache) > CACHED_REPORTS:
            _cache.popitem(last=False)
    return done


def window_report_html(loop: LoopReader, row: dict[str, Any]) -> str:
    """The report page of the window ``row`` of ``loop`` (an explanation page when it fails).

    The analysis is kept; the proposals from the window are read afresh for every page (one
    may be filed, or change, after the first look).
    """
    from fuelid.htmlreport import render_report

    analysed = _analysed(loop, row)
    if isinstance(analysed, str):
        return analysed
    analysis, figures = analysed
    return render_report(_with_notices(analysis, _proposal_notices(loop, row, analysis)), figures)


# --- the online proposals from the window ---------------------------------------------------


def _proposal_notices(loop: LoopReader, row: dict[str, Any], analysis: LogAnalysis) -> list[str]:
    """One notice per proposal the service filed from this window (none without a model)."""
    model_id = row.get("model_id")
    if model_id is None:
        return []
    history = loop.history()
    mine = [p for p in history.get("proposals") or [] if p.get("model_id") == model_id]
    if not mine:
        return []
    windows = {
        int(w["model_id"]): int(w["id"])
        for w in history.get("windows") or []
        if w.get("model_id") is not None
    }
    pi = analysis.tuning.pi
    return [
        proposal_notice(
            p,
            pi,
            window=row,
            page_model=analysis.model_result.model,
            page_method=analysis.settings.tune_from,
            windows_of_models=windows,
        )
        for p in mine
    ]


def _ideal(value: Any) -> tuple[float, float] | None:
    """(Kc, Ti) of a stored ``{"Kc", "Ti"}``; None when either is missing or not positive."""
    if not isinstance(value, Mapping):
        return None
    try:
        Kc, Ti = float(value["Kc"]), float(value["Ti"])
    except (KeyError, TypeError, ValueError):
        return None
    return (Kc, Ti) if Kc > 0.0 and Ti > 0.0 and math.isfinite(Kc + Ti) else None


def _apart(a: tuple[float, float] | None, b: tuple[float, float] | None) -> float:
    """The larger relative difference of Kc and Ti (0 when either pair is unknown)."""
    if a is None or b is None:
        return 0.0
    return max(abs(x / y - 1.0) for x, y in zip(a, b, strict=True))


def _gains_text(g: tuple[float, float]) -> str:
    return f"Kc {g[0]:.4g}, Ti {g[1]:.4g} s"


def _windows_text(model_ids: Sequence[Any], windows_of_models: Mapping[int, int]) -> str:
    names = []
    for m in model_ids:
        w = windows_of_models.get(int(m))
        names.append(f"#{w}" if w is not None else f"of model #{m}")
    return ", ".join(names)


def proposal_notice(
    proposal: Mapping[str, Any],
    pi: PISettings,
    *,
    window: Mapping[str, Any],
    page_model: ProcessModel | None = None,
    page_method: str = "oe",
    windows_of_models: Mapping[int, int] | None = None,
) -> str:
    """The notice of an online proposal from a window, beside the window report's gains.

    Parameters
    ----------
    proposal : dict
        The proposal as :func:`fuelid.online.report.proposal_json` gives it (its ``decision``:
        what the gains rest on, ideal form).
    pi : PISettings
        The gains the page shows (ideal form, Kc [V per L/min], Ti [s]).
    window : dict
        The window's stored row (its ``model_id`` and its ``detail``: the service's fit).
    page_model : ProcessModel, optional
        The model the page's gains come from.
    page_method : str
        The estimator of ``page_model``.
    windows_of_models : dict, optional
        Model id → window id, to name the agreeing windows.

    Returns
    -------
    str
        "the online proposal #N from this window: Kc …, Ti … s (rule …)", then either that the
        page's gains are the same within :data:`SAME_GAINS` or why they differ, step by step
        from the page's gains to the proposal's: another rule or PLC period, the service's own
        fit of the window, the weighted mean of the agreeing windows' models, the gain bounds,
        the partial move (``move_fraction``), the detuning for Ms.

    Examples
    --------
    >>> from fuelid.tuning import PISettings
    >>> pi = PISettings(rule="simc", Kc=0.04, Ti=1.0, control_period=1.0)
    >>> p = {"id": 3, "decision": {"rule": "simc", "move_fraction": 0.5,
    ...      "model_ids": [7], "window_gains": [{"model_id": 7, "Kc": 0.04, "Ti": 1.0}],
    ...      "ideal": {"old": {"Kc": 0.01, "Ti": 1.0}, "target": {"Kc": 0.04, "Ti": 1.0},
    ...                "target_unclipped": {"Kc": 0.04, "Ti": 1.0},
    ...                "undetuned": {"Kc": 0.02, "Ti": 1.0}, "new": {"Kc": 0.02, "Ti": 1.0}}}}
    >>> print(proposal_notice(p, pi, window={"model_id": 7}))  # doctest: +NORMALIZE_WHITESPACE
    the online proposal #3 from this window: Kc 0.02, Ti 1 s (rule simc); it differs from the
    gains above (Kc 0.04, Ti 1 s) by up to 50 %: the proposal moves only 50 % of the way
    (move_fraction, geometric) from the gains in the PLC then (Kc 0.01, Ti 1 s) toward the
    rule's target (Kc 0.04, Ti 1 s)
    """
    decision = proposal.get("decision") or {}
    ideal = decision.get("ideal") or {}
    new = _ideal(ideal.get("new"))
    rule = decision.get("rule")
    head = f"the online proposal #{proposal.get('id')} from this window"
    rule_text = f" (rule {rule})" if rule else ""
    if new is None:
        block = proposal.get("new") or {}
        units = proposal.get("gain_units") or {}
        return (
            f"{head}: Kc {block.get('Kc')} {units.get('Kc', '')}, Ti {block.get('Ti')} "
            f"{units.get('Ti', '')} in the block's units{rule_text}; it recorded no ideal-form "
            "gains to compare with the gains above"
        ).replace("  ", " ")
    head = f"{head}: {_gains_text(new)}{rule_text}"
    page = (pi.Kc, pi.Ti)
    apart = _apart(new, page)
    if apart <= SAME_GAINS:
        return f"{head}: the gains above, within {100.0 * SAME_GAINS:g} %"
    reasons = _why(decision, pi, window, page_model, page_method, windows_of_models or {})
    why = "; ".join(reasons) if reasons else "for a reason the proposal did not record"
    return (
        f"{head}; it differs from the gains above ({_gains_text(page)}) by up to "
        f"{100.0 * apart:.0f} %: {why}"
    )


def _why(
    decision: Mapping[str, Any],
    pi: PISettings,
    window: Mapping[str, Any],
    page_model: ProcessModel | None,
    page_method: str,
    windows_of_models: Mapping[int, int],
) -> list[str]:
    """Each step from the page's gains to the proposal's that moves them by more than 1 %."""
    ideal = decision.get("ideal") or {}
    reasons = []
    rule = decision.get("rule")
    if rule and rule != pi.rule:
        reasons.append(f"the proposal used rule {rule}, this page {pi.rule}")
    h = decision.get("control_period_s")
    if isinstance(h, int | float) and abs(h - pi.control_period) > SAME_GAINS * max(h, 1e-9):
        reasons.append(
            f"the proposal's PLC period was {h:g} s, this page's {pi.control_period:g} s"
        )
    step = (pi.Kc, pi.Ti)
    own = next(
        (
            _ideal(w)
            for w in decision.get("window_gains") or []
            if w.get("model_id") == window.get("model_id")
        ),
        None,
    )
    if own is not None:
        if _apart(own, step) > SAME_GAINS:
            reasons.append(_own_fit(own, window, page_model, page_method))
        step = own
    unclipped = _ideal(ideal.get("target_unclipped"))
    model_ids = list(decision.get("model_ids") or [])
    if unclipped is not None:
        if _apart(unclipped, step) > SAME_GAINS:
            reasons.append(
                "the rule's target rests on the weighted mean of the models of windows "
                f"{_windows_text(model_ids, windows_of_models)} ({_gains_text(unclipped)})"
            )
        step = unclipped
    target = _ideal(ideal.get("target"))
    if target is not None:
        if _apart(target, step) > SAME_GAINS:
            reasons.append(
                f"the target was clipped to the gain bounds{_bounds_text(decision)}, to "
                f"{_gains_text(target)}"
            )
        step = target
    undetuned = _ideal(ideal.get("undetuned"))
    old = _ideal(ideal.get("old"))
    if undetuned is not None and _apart(undetuned, step) > SAME_GAINS:
        fraction = decision.get("move_fraction")
        share = (
            f"{100.0 * fraction:g} % of the way"
            if isinstance(fraction, int | float)
            else "part of the way"
        )
        start = f"from the gains in the PLC then ({_gains_text(old)}) " if old else ""
        reasons.append(
            f"the proposal moves only {share} (move_fraction, geometric) {start}toward the "
            f"rule's target ({_gains_text(step)})"
        )
    factor = decision.get("detune_factor")
    if isinstance(factor, int | float) and factor < 1.0 - SAME_GAINS:
        ms = decision.get("ms_target")
        bound = f" ≤ {ms:g}" if isinstance(ms, int | float) else ""
        reasons.append(f"Kc was detuned ×{factor:.3f} to keep Ms{bound} on every check")
    return reasons


def _bounds_text(decision: Mapping[str, Any]) -> str:
    bounds = decision.get("bounds") or {}
    try:
        kc, ti = bounds["Kc"], bounds["Ti"]
        return (
            f" (Kc {float(kc[0]):.4g}–{float(kc[1]):.4g}, Ti {float(ti[0]):.4g}–"
            f"{float(ti[1]):.4g} s: gain_bounds × the commissioning gains)"
        )
    except (KeyError, IndexError, TypeError, ValueError):
        return " (gain_bounds × the commissioning gains)"


def _own_fit(
    own: tuple[float, float],
    window: Mapping[str, Any],
    page_model: ProcessModel | None,
    page_method: str,
) -> str:
    """The service's fit of the window against the page's."""
    detail = window.get("detail") or {}
    method = detail.get("method") or "own"
    stored = detail.get("model")
    model: Mapping[str, Any] = stored if isinstance(stored, Mapping) else {}
    theirs = _model_text(model.get("K"), model.get("T"), model.get("delay"))
    page = "" if page_model is None else _model_text(page_model.K, page_model.T, page_model.delay)
    return (
        f"the service's {method} fit of this window{theirs} gives {_gains_text(own)} by the "
        f"rule; this page fits the same samples again ({page_method}{page})"
    )


def _model_text(K: Any, T: Any, delay: Any) -> str:
    try:
        return f": K {float(K):.4g} (L/min)/V, T {float(T):.3g} s, θ {float(delay):.3g} s"
    except (TypeError, ValueError):
        return ""
