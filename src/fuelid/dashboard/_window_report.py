"""The HTML report of one window, as ``fuelid report`` writes it for a log.

The window's samples are analysed as a log (both identifications, the tuning, the check over
fuel temperature) and rendered with the report's template, the figures embedded. The gains come
from the estimator the service's gate judged the window with (its ``detail.method``: "oe" or
"pem"), so the report names the model the window page names. The plant file is the one the
service ran with (its path and SHA-256 are in the service's record), when it is still there with
the same hash; otherwise the built-in reference plant stands in, and the report says so, as
``fuelid report`` does without ``--plant``. The page names the plant file by its base name and
SHA-256 prefix, never by its folder: no server path reaches a page.

An analysis takes seconds (about 2.5 s of one core for a 10-minute window at 50 Hz, the six
figures two thirds of it, the plant's linearisations another second the first time;
docs/benchmarks/window_report.md), so the last :data:`CACHED_REPORTS` analyses are kept in
memory, and a :class:`ReportPrefetcher` (which the dashboard's server starts, through
:class:`~fuelid.dashboard._registry.Loops`) makes the newest windows' ahead, in the background,
as soon as the service has judged them: their first request is then served from memory. A
report made ahead gives way, between its steps, to a request's own (the two would share one
core). A request for a window being made waits for it rather than making it twice. The page is
rendered afresh each time.

The analyses of a store's loop and its plant's linearisations are also kept on disk, beside the
store (:mod:`fuelid.dashboard._report_files`): a restarted dashboard serves the reports it made
before at once, and makes a new one without linearising the plant again.

When the online service filed a proposal from this window (the proposal's ``model_id`` is the
window's), the page's notices say so, with the proposal's gains in the same ideal form as the
page's "PI gains to enter in the PLC", and, when the two differ by more than
:data:`SAME_GAINS` (relative), why: another rule or PLC period, the service's own fit of the
window, the weighted mean of the agreeing windows' models, the gain bounds, the partial move
(``move_fraction``), the detuning for Ms (:func:`proposal_notice`, from what the proposal
recorded: :func:`fuelid.online._report.decision_json`).
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, TypeGuard

from fuelid.dashboard import _report_files as report_files
from fuelid.dashboard._source import LoopReader
from fuelid.errors import FuelidError
from fuelid.workflow import LogAnalysis

if TYPE_CHECKING:
    from fuelid.htmlreport import ReportFigure
    from fuelid.model import ProcessModel
    from fuelid.tuning import CaseCache, PISettings
    from fuelid.workflow import AnalysisSettings

__all__ = [
    "CACHED_PLANTS",
    "CACHED_REPORTS",
    "PREFETCH_EVERY_S",
    "PREFETCH_MAX",
    "PREFETCH_NEWEST",
    "SAME_GAINS",
    "ReportPrefetcher",
    "plant_file_name",
    "proposal_notice",
    "report_method",
    "warm_up",
    "window_report_html",
]

CACHED_REPORTS = 12
"""Analyses kept in memory (about 3.3 MB each for a 10-minute window at 50 Hz)."""
PREFETCH_EVERY_S = 5.0
"""How often the prefetcher looks for a newly judged window [s]."""
PREFETCH_NEWEST = 3
"""Windows of each loop made ahead: the newest three (a proposal rests on two or three)."""
PREFETCH_MAX = CACHED_REPORTS // 2
"""Windows made ahead in all, the newest of every loop first: half the cache, the other half
left to the windows opened on request."""
CACHED_PLANTS = 4
"""Plants whose linearisations are kept (one per plant file)."""
CACHED_CASES = 2048
"""Linearisations kept per plant (about 4 kB each in memory): each window's report adds a few,
at its own fuel temperature and command, so a dashboard left open for months would otherwise
grow by them without end; the oldest go first."""
SAME_GAINS = 0.01
"""Gains within this of each other (relative, Kc and Ti each) are the same gains [-]."""

_Key = tuple[str, str, int]
_Analysed = tuple[LogAnalysis, list["ReportFigure"]] | str
_cache: OrderedDict[_Key, _Analysed] = OrderedDict()
_running: dict[_Key, threading.Event] = {}
"""The analyses being made now: a second request waits for the first one's."""
_lock = threading.Lock()
_plant_caches: OrderedDict[str, CaseCache] = OrderedDict()
"""The plants' linearisations by plant file SHA-256: the check over temperature and the
schedule of every report on one plant share them (each is the same plant at the same point)."""
_plant_read: dict[tuple[Path, str], int] = {}
"""Linearisations of a plant read from, or written to, a store's folder: how many."""
_asked: list[_Key] = []
"""The analyses being made for a request now (not ahead): the prefetcher waits for them."""
_no_request = threading.Event()
_no_request.set()
_this_thread = threading.local()
"""``ahead``: this thread makes a report ahead (it gives way to requests: :func:`_give_way`)."""
REFERENCE_PLANT = "built-in reference plant"
"""The key of the reference plant's linearisations (a plant file's is its SHA-256)."""


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


def plant_file_name(path: str, digest: str | None) -> str:
    """How a page names a plant file: its base name and SHA-256 prefix, never its folder.

    Examples
    --------
    >>> plant_file_name("/srv/plants/tunnel2.toml", "9f86d081884c7d659a2feaa0c55ad015")
    'tunnel2.toml (SHA-256 9f86d081884c)'
    >>> plant_file_name("tunnel2.toml", None)
    'tunnel2.toml'
    """
    name = path.replace("\\", "/").rsplit("/", 1)[-1]  # a Windows service's path too
    return f"{name} (SHA-256 {digest[:12]})" if digest else name


def _plant_file(loop: LoopReader) -> tuple[str, str] | None:
    """The service's plant file and its SHA-256, when it is still there unchanged."""
    from fuelid.online import plant_hash

    settings = (loop.status().get("service") or {}).get("settings") or {}
    path, digest = loop.plant_file(), settings.get("plant_hash")
    if path and digest and Path(path).is_file() and plant_hash(path) == digest:
        return str(path), str(digest)
    return None


def _plant(loop: LoopReader) -> tuple[Any, str]:
    """The service's plant file when it is still there unchanged, else the reference plant.

    The plant source's ``path`` is what the page shows (:func:`plant_file_name`): the file is
    loaded here, by its full path, and nothing later reads it again. With it, the key of the
    plant's linearisations (:func:`_linearisations`): the file's SHA-256.
    """
    from fuelid.plant import load_plant_config
    from fuelid.workflow import PlantSource

    found = _plant_file(loop)
    if found is None:
        return PlantSource(load_plant_config(None)), REFERENCE_PLANT
    path, digest = found
    return PlantSource(load_plant_config(path), path=plant_file_name(path, digest)), digest


def _linearisations(plant_key: str, folder: Path | None = None) -> CaseCache:
    """The linearisations of one plant the reports share (a few plants at most are kept).

    The first time a store's ``folder`` is named, the ones a dashboard kept there are read.
    """
    with _lock:
        cache = _plant_caches.pop(plant_key, None)
        _plant_caches[plant_key] = {} if cache is None else cache  # the newest last
        while len(_plant_caches) > CACHED_PLANTS:
            _plant_caches.popitem(last=False)
        cache = _plant_caches[plant_key]
        _drop_oldest(cache, CACHED_CASES)
        unread = folder is not None and (folder, plant_key) not in _plant_read
        if folder is not None:
            _plant_read.setdefault((folder, plant_key), 0)
    if unread and folder is not None:
        kept = report_files.load(folder, report_files.file_name("plant", [plant_key]))
        if _are_linearisations(kept):
            for case, found in kept.items():
                cache.setdefault(case, found)
            with _lock:
                _plant_read[(folder, plant_key)] = len(kept)
    return cache


def _drop_oldest(cache: CaseCache, keep: int) -> None:
    """Drop the oldest entries of ``cache`` (a dict keeps insertion order) beyond ``keep``.

    >>> cache = {(float(i), 1.0): i for i in range(5)}
    >>> _drop_oldest(cache, 2)  # type: ignore[arg-type]
    >>> sorted(cache)
    [(3.0, 1.0), (4.0, 1.0)]
    """
    for case in list(cache)[: max(len(cache) - keep, 0)]:
        cache.pop(case, None)


def _are_linearisations(kept: Any) -> TypeGuard[CaseCache]:
    """``kept`` is a plant's linearisations as :func:`_keep_linearisations` wrote them."""
    from fuelid.model import ProcessModel
    from fuelid.plant import LinearPlant

    return isinstance(kept, dict) and all(
        isinstance(case, tuple)
        and isinstance(found, tuple)
        and len(found) == 2
        and isinstance(found[0], LinearPlant)
        and isinstance(found[1], ProcessModel)
        for case, found in kept.items()
    )


def _keep_linearisations(folder: Path | None, plant_key: str, cache: CaseCache) -> None:
    """Write the plant's linearisations to the store's folder when they grew since."""
    if folder is None:
        return
    snapshot = dict(cache)  # one C call: another thread may add to it meanwhile
    with _lock:
        if _plant_read.get((folder, plant_key), 0) >= len(snapshot):
            return
        _plant_read[(folder, plant_key)] = len(snapshot)
    report_files.save(folder, report_files.file_name("plant", [plant_key]), snapshot)


def report_method(row: Mapping[str, Any]) -> Literal["oe", "pem"]:
    """The estimator the service's gate judged the window with: "oe" or "pem" ("oe" unfitted).

    >>> report_method({"detail": {"method": "pem"}})
    'pem'
    >>> report_method({"detail": {"reason": "too few samples"}})
    'oe'
    """
    method = (row.get("detail") or {}).get("method")
    return "pem" if method == "pem" else "oe"


def _settings(loop: LoopReader, row: Mapping[str, Any]) -> AnalysisSettings:
    """The report's settings from the service's: its rule, PI period, spans and estimator.

    The site file's control period and spans are the user's facts (none is assumed); a service
    that wrote no settings leaves the period unknown, and the page then says why it has none.
    The gains come from the window's own estimator (:func:`report_method`).
    """
    from fuelid.workflow import AnalysisSettings

    settings = (loop.status().get("service") or {}).get("settings") or {}
    sampling = settings.get("sampling") or {}
    controller = settings.get("controller") or {}
    rule = settings.get("rule")
    return AnalysisSettings(
        tune_from=report_method(row),
        accept_signals=True,
        rule=rule if isinstance(rule, str) else AnalysisSettings.rule,
        control_period=sampling.get("control_period_s"),
        control_period_basis="site file",
        site_spans=(controller.get("u_span_V"), controller.get("y_span_Lpm")),
    )


def _key(loop: LoopReader, row: Mapping[str, Any]) -> _Key:
    return (loop.loop_id, str(loop.identity().get("store_uuid")), int(row["id"]))


def _folder(loop: LoopReader) -> Path | None:
    """Where a loop's reports are kept on disk: beside its store file (a central loop: none)."""
    path = getattr(loop, "path", None)  # a store file's loop (SQLiteLoop) names its file
    return report_files.report_folder(path) if isinstance(path, Path) else None


def _give_way() -> None:
    """In a report made ahead: wait while a request's report is being made (it goes first)."""
    if getattr(_this_thread, "ahead", False):
        _no_request.wait()


def _analyse(loop: LoopReader, row: dict[str, Any]) -> _Analysed:
    """The window's analysis and figures, or its explanation page (nothing kept)."""
    from fuelid.htmlreport import ReportFigure, figure_png, report_figures
    from fuelid.store import iodata_from_samples
    from fuelid.workflow import analyse_log

    samples = loop.samples(float(row["t_from"]), float(row["t_to"]))
    title = f"Window {row['id']} of loop {loop.loop_id}"
    try:
        data = iodata_from_samples(samples, loop.identity().get("period_s"), source=title)
        plant, plant_key = _plant(loop)
        linearisations = _linearisations(plant_key, _folder(loop))
        _give_way()
        analysis = analyse_log(data, plant, _settings(loop, row), cache=linearisations)
        _keep_linearisations(_folder(loop), plant_key, linearisations)
        _give_way()
        figures = []
        for key, (fig, caption) in report_figures(analysis).items():
            _give_way()  # a figure is a fraction of a second: a request waits no longer
            figures.append(ReportFigure(key, caption, figure_png(fig)))
    except FuelidError as error:
        return _error_page(title, f"the report could not be made: {error}")
    return (analysis, figures)


def _report_inputs(loop: LoopReader, row: Mapping[str, Any]) -> list[Any]:
    """What a window's report is made from, to name its file (:func:`report_files.file_name`)."""
    identity = loop.identity()
    found = _plant_file(loop)
    return [
        loop.loop_id,
        identity.get("store_uuid"),
        identity.get("period_s"),
        int(row["id"]),
        float(row["t_from"]),
        float(row["t_to"]),
        repr(_settings(loop, row)),
        None if found is None else [found[1], plant_file_name(*found)],
    ]


def _is_report(kept: Any) -> TypeGuard[tuple[LogAnalysis, list[ReportFigure]]]:
    """``kept`` is an analysis and its figures, as :func:`_analyse` makes them."""
    from fuelid.htmlreport import ReportFigure

    return (
        isinstance(kept, tuple)
        and len(kept) == 2
        and isinstance(kept[0], LogAnalysis)
        and isinstance(kept[1], list)
        and all(isinstance(figure, ReportFigure) for figure in kept[1])
    )


def _kept_or_made(loop: LoopReader, row: dict[str, Any]) -> _Analysed:
    """The window's analysis a dashboard kept beside the store, else made now (and kept)."""
    folder = _folder(loop)
    if folder is None:
        return _analyse(loop, row)
    name = report_files.file_name("report", _report_inputs(loop, row))
    kept = report_files.load(folder, name)
    if _is_report(kept):
        return kept
    done = _analyse(loop, row)
    if not isinstance(done, str):  # an explanation page is not kept: its reason may pass
        report_files.save(folder, name, done)
    return done


def _analysed(loop: LoopReader, row: dict[str, Any], ahead: bool = False) -> _Analysed:
    """The window's analysis and figures (kept in memory), or its explanation page.

    Made once: a request for a window another thread is making waits for that one. ``ahead``:
    made by the prefetcher, which lets a request's analysis go first (:func:`_asking`).
    """
    key = _key(loop, row)
    while True:
        with _lock:
            if key in _cache:
                _cache.move_to_end(key)
                return _cache[key]
            running = _running.get(key)
            if running is None:
                running = _running[key] = threading.Event()
                break
        running.wait()  # then read it kept (or make it, if it failed or was dropped)
    try:
        with _making_ahead() if ahead else _asking(key):
            done = _kept_or_made(loop, row)
        with _lock:
            _cache[key] = done
            while len(_cache) > CACHED_REPORTS:
                _cache.popitem(last=False)
    finally:
        with _lock:
            _running.pop(key, None)
        running.set()
    return done


@contextlib.contextmanager
def _making_ahead() -> Iterator[None]:
    """The calling thread makes a report ahead: it gives way to requests (:func:`_give_way`)."""
    _this_thread.ahead = True
    try:
        yield
    finally:
        _this_thread.ahead = False


@contextlib.contextmanager
def _asking(key: _Key) -> Iterator[None]:
    """A request's analysis under way: the prefetcher starts none meanwhile."""
    with _lock:
        _asked.append(key)
        _no_request.clear()
    try:
        yield
    finally:
        with _lock:
            _asked.remove(key)
            if not _asked:
                _no_request.set()


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


# --- made ahead -------------------------------------------------------------------------------


def warm_up() -> None:
    """Load what a report's figures are drawn with: one small figure drawn as the report's are.

    matplotlib, its Agg canvas, PIL and the fonts take about a second to load the first time,
    which a restarted dashboard whose reports were kept would otherwise pay at the first report
    it makes on request. The prefetcher does it as it starts (:meth:`ReportPrefetcher.start`).
    """
    from matplotlib.figure import Figure

    from fuelid.htmlreport import figure_png

    fig = Figure(figsize=(2.0, 1.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.0, 1.0], label="flow [L/min]")
    ax.set_xlabel("time [s]")
    ax.legend()
    figure_png(fig)


class ReportPrefetcher:
    """Makes the reports of the loops' newest windows ahead, in a background thread.

    Every ``every_s`` seconds the newest :data:`PREFETCH_NEWEST` windows of each loop
    ``loops()`` gives are looked at, the newest of every loop first, at most
    :data:`PREFETCH_MAX` in all (the cache keeps them, :data:`CACHED_REPORTS`); one not made yet
    is analysed and kept, so the first request of a window an operator opens after a proposal
    (which rests on the newest few windows) is served from memory. What the figures are drawn
    with is loaded when it starts (:func:`warm_up`). A request's own analysis
    goes first: none is started ahead while one runs. Each window is made once:
    one dropped from the cache since is made again only on request. The cost is one analysis
    per judged window (about 2.5 s of one core per window of the service's schedule, every 5
    minutes by default), and a few at the dashboard's first start (a restart reads them back
    from beside the store), spent only on local stores (the loops ``loops()`` gives: a central
    loop's samples may not be at hand).

    Parameters
    ----------
    loops : callable
        The loops to watch, called at every look (the local stores now).
    every_s : float
        How often to look [s].
    """

    def __init__(
        self, loops: Callable[[], Sequence[LoopReader]], every_s: float = PREFETCH_EVERY_S
    ) -> None:
        self._loops = loops
        self.every_s = every_s
        self._made: set[_Key] = set()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def wanted(self) -> list[tuple[_Key, LoopReader, dict[str, Any]]]:
        """The windows to have ready: the newest of every loop first, then the next newest."""
        ranked = []
        for loop in self._loops():
            newest_first = reversed(loop.recent_windows(PREFETCH_NEWEST))
            ranked += [(rank, loop, row) for rank, row in enumerate(newest_first)]
        ranked.sort(key=lambda item: item[0])  # stable: the loops' order within a rank
        return [(_key(loop, row), loop, row) for _, loop, row in ranked[:PREFETCH_MAX]]

    def run_once(self) -> int:
        """Make the reports of :meth:`wanted` not made yet; how many were made."""
        wanted = self.wanted()
        made = 0
        for key, loop, row in wanted:
            if self._stop.is_set():
                break
            if key in self._made:
                continue
            while not _no_request.wait(0.2):  # a request's analysis goes first
                if self._stop.is_set():
                    return made
            self._made.add(key)
            _analysed(loop, row, ahead=True)
            made += 1
        self._made &= {key for key, _, _ in wanted}  # what is no longer wanted is forgotten
        return made

    def _run(self) -> None:
        while not self._stop.is_set():
            with contextlib.suppress(Exception):  # a store closed or replaced: look again
                self.run_once()
            self._stop.wait(self.every_s)

    def start(self) -> ReportPrefetcher:
        """Load what the figures are drawn with, then start looking in a daemon thread.

        The loading (:func:`warm_up`) is done here, before the dashboard says it is ready: in
        the background it would share the one core a first request's report has. Returns
        itself.
        """
        if self._thread is None:
            with contextlib.suppress(Exception):  # only sooner: a report draws without it
                warm_up()
            self._thread = threading.Thread(target=self._run, name="report-prefetch", daemon=True)
            self._thread.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop looking; waits up to ``timeout_s`` [s] for an analysis under way to end."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)


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
        The proposal as :func:`fuelid.online._report.proposal_json` gives it (its ``decision``:
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
