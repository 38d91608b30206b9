"""The benchmark tables in the docs: written by the benchmark scripts, never typed by hand.

Each ``benchmarks/bench_<name>.py`` that prints a table also writes ``docs/benchmarks/<name>.md``
through this module, and every page opens with the line that says what produced its numbers:
the machine (CPU model, cores), the date, the Python and numpy versions and the exact command.
Numbers without that line cannot be compared (a shared 2-core machine is several times slower
than an idle one), so no page is written without it.

Two ways in:

- :class:`Table` for a script that builds its rows itself: ``table.add(...)`` prints the row as
  it always did and keeps it; :func:`write_page` writes the kept tables as Markdown tables;
- :func:`run_to_docs` for a script whose output is already a readable fixed-width table: it runs
  the script's ``main`` with its standard output copied into the page verbatim.

``python benchmarks/_docs_table.py`` writes a "not yet run: ``make bench``" page for every
benchmark that has none and the index ``docs/benchmarks/index.md`` (``make docs-assets`` runs it),
so the site lists every benchmark before the long ones have run. ``make test`` never writes here.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io
import os
import platform
import shlex
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO, TypeVar

ROOT = Path(__file__).resolve().parent.parent
PAGES = ROOT / "docs" / "benchmarks"

#: every benchmark page: name (``bench_<name>.py`` writes ``<name>.md``), title, the command
#: ``make bench`` runs. bench_gate_study writes its own page (the explanation of the gate).
BENCHMARKS: dict[str, tuple[str, str]] = {
    "simulate": ("Simulation speed", "benchmarks/bench_simulate.py"),
    "identify_speed": ("Identification speed", "benchmarks/bench_identify_speed.py"),
    "day_log": (
        "A day of data: identify and report against read-and-solve",
        "benchmarks/bench_day_log.py",
    ),
    "identify_accuracy": (
        "Identification accuracy against the Cramér–Rao bound",
        "benchmarks/bench_identify_accuracy.py",
    ),
    "default_path": (
        "The default identify path against the Cramér–Rao bound",
        "benchmarks/bench_default_path.py --runs 500",
    ),
    "oe_coverage": (
        "Output-error intervals under coloured noise",
        "benchmarks/bench_oe_coverage.py",
    ),
    "pem": ("Prediction error against output error", "benchmarks/bench_pem.py --runs 1000"),
    "refdata": ("Real records (DaISy)", "benchmarks/bench_refdata.py"),
    "tuning_sweep": ("Tuning sweep speed", "benchmarks/bench_tuning_sweep.py"),
    "cold_start": ("Cold start of the command line", "benchmarks/bench_cold_start.py"),
    "commands_loaded": (
        "Commands on a loaded machine",
        "benchmarks/bench_commands_loaded.py",
    ),
    "store": ("The SQLite store", "benchmarks/bench_store.py"),
    "archive": ("The raw archive", "benchmarks/bench_archive.py"),
    "virtual_plant": ("The virtual PLC's speed", "benchmarks/bench_virtual_plant.py"),
    "acquisition": ("Acquisition at 50 Hz", "benchmarks/bench_acquisition.py --minutes 2"),
    "online": ("The online service's cost", "benchmarks/bench_online.py --minutes 2"),
    "window": ("One online window, today's against the fast path", "benchmarks/bench_window.py"),
    "greybox": ("Gray-box estimation", "benchmarks/bench_greybox.py --runs 200"),
    "greybox_peer": (
        "Gray-box fit against a hand-written peer",
        "benchmarks/bench_greybox_peer.py",
    ),
    "greybox_peer_real": (
        "Gray-box fit against a hand-written peer: a real-like record",
        "benchmarks/bench_greybox_peer.py --only real-like --repeats 1",
    ),
    "greybox_smoothing": (
        "Gray-box: an exact kink against smoothed ones",
        "benchmarks/bench_greybox_smoothing.py --runs 100",
    ),
    "calibration": (
        "Plant calibration",
        "benchmarks/bench_calibration.py --runs 200 --minutes 2",
    ),
    "calibration_timing": ("Plant calibration speed", "benchmarks/bench_calibration.py --timing"),
    "dashboard": ("The dashboard's speed", "benchmarks/bench_dashboard.py"),
    "window_report": (
        "The dashboard's window report: first request, quiet and loaded",
        "benchmarks/bench_window_report.py",
    ),
    "dashboard_page": (
        "The loop page's first view with a year of windows",
        "benchmarks/bench_dashboard_page.py",
    ),
    "dashboard_soak": (
        "A loop page left open for half an hour",
        "benchmarks/bench_dashboard_soak.py",
    ),
    "central": ("Central ingest from many senders", "benchmarks/bench_central.py"),
    "reidentify": ("Re-identification on Dask", "benchmarks/bench_reidentify.py"),
    "excitation": (
        "The designed test signal against a PRBS at the same standard error of K",
        "benchmarks/bench_excitation.py",
    ),
    "trust": (
        "What fuelid tune prints against the truth, on loops unlike the reference plant",
        "benchmarks/bench_trust.py",
    ),
}

_T = TypeVar("_T")

#: the marker a placeholder page carries, so the index can tell it from a real run
NOT_RUN = "Not yet run:"


def cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo`` on Linux), else what platform knows."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.lower().startswith("model name"):
                return " ".join(line.split(":", 1)[1].split())
    return platform.processor() or platform.machine() or "unknown CPU"


def command_line(argv: Sequence[str] | None = None) -> str:
    """The exact command that is running, as it can be typed again from the repository root."""
    args = list(sys.argv if argv is None else argv)
    script = Path(args[0]).resolve()
    with contextlib.suppress(ValueError):
        script = script.relative_to(ROOT)
    return shlex.join(["python", str(script), *args[1:]])


def provenance(seconds: float | None = None, argv: Sequence[str] | None = None) -> str:
    """The page's header line: machine, date, Python and numpy versions, the exact command."""
    try:
        import numpy

        numpy_version = numpy.__version__
    except ImportError:  # pragma: no cover - every benchmark imports numpy
        numpy_version = "absent"
    took = f", {seconds:.0f} s wall time" if seconds is not None else ""
    # the load says whether the seconds are an idle machine's: other work shares the cores
    load = f", load average {os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else ""
    return (
        f"Measured on {datetime.date.today().isoformat()}: {cpu_model()}, {os.cpu_count()} cores"
        f"{load}, Python {platform.python_version()}, numpy {numpy_version}{took}. "
        f"Command: `{command_line(argv)}`. Written by the script; do not edit by hand."
    )


def _cell(value: object) -> str:
    return str(value).replace("|", "\\|")


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table (pipes in cells escaped)."""
    lines = [
        "| " + " | ".join(_cell(h) for h in header) + " |",
        "|" + "---|" * len(header),
    ]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


@dataclass
class Table:
    """A table printed row by row as the benchmark runs and kept for the docs page.

    ``widths`` and ``formats`` shape the printed line only (the page gets the formatted text of
    each cell without the padding); a format is a format spec such as ``".3f"`` or ``""``.
    """

    header: Sequence[str]
    formats: Sequence[str]
    widths: Sequence[int]
    title: str = ""
    rows: list[list[str]] = field(default_factory=list)

    def _line(self, cells: Sequence[str]) -> str:
        # the first column (the case) is left-aligned, the numbers right-aligned
        parts = [
            f"{cell:{'<' if i == 0 else '>'}{width}s}"
            for i, (cell, width) in enumerate(zip(cells, self.widths, strict=True))
        ]
        return " ".join(parts)

    def print_header(self, out: TextIO | None = None) -> None:
        """Print the header line (the title first, when there is one)."""
        stream = sys.stdout if out is None else out
        if self.title:
            print(self.title, file=stream)
        print(self._line(list(self.header)), file=stream, flush=True)

    def add(self, *values: object, out: TextIO | None = None) -> None:
        """Format, print and keep one row."""
        cells = [format(v, f) for v, f in zip(values, self.formats, strict=True)]
        self.rows.append(cells)
        print(self._line(cells), file=sys.stdout if out is None else out, flush=True)

    def markdown(self) -> str:
        """The kept rows as a Markdown table, under the title in bold when there is one."""
        table = markdown_table(self.header, self.rows)
        return f"**{self.title}**\n\n{table}" if self.title else table


RESULTS_START = "<!-- --8<-- [start:results] -->"
RESULTS_END = "<!-- --8<-- [end:results] -->"
"""The markers around a page's results (pymdownx.snippets sections)."""


def _page_path(name: str, docs: Path | None) -> Path:
    return (PAGES if docs is None else docs) / f"{name}.md"


def write_page(
    name: str,
    intro: str,
    parts: Sequence[str | Table],
    seconds: float | None = None,
    docs: Path | None = None,
) -> Path:
    """Write ``docs/benchmarks/<name>.md``: title, provenance line, intro, tables; the index too.

    ``parts`` are :class:`Table` objects or Markdown text (notes between tables).
    """
    title = BENCHMARKS.get(name, (name.replace("_", " ").capitalize(), ""))[0]
    body = [p.markdown() if isinstance(p, Table) else p for p in parts]
    # the results between snippet markers: a guide quotes them with
    # --8<-- "docs/benchmarks/<name>.md:results" and shows what the page shows
    body = [RESULTS_START, *body, RESULTS_END]
    text = "\n\n".join([f"# {title}", provenance(seconds), intro.strip(), *body]) + "\n"
    path = _page_path(name, docs)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    write_index(path.parent)
    print(f"wrote {path}")
    return path


class _Tee(io.TextIOBase):
    """Standard output that is also kept: the script prints as ever, the page gets a copy."""

    def __init__(self, stream: TextIO) -> None:
        self.stream, self.kept = stream, io.StringIO()

    def write(self, text: str) -> int:
        self.kept.write(text)
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()


@contextlib.contextmanager
def _teed() -> Iterator[_Tee]:
    tee = _Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        yield tee


def run_to_docs(name: str, main: Callable[[], _T], doc: str | None) -> _T:
    """Run a benchmark's ``main`` and write what it printed as its docs page, verbatim.

    ``doc`` (the script's module docstring) gives the page its introduction: the text before the
    line that says how to run it. ``--help`` and a failing run write nothing. Returns what
    ``main`` returned (an exit code, for some).
    """
    if any(arg in ("-h", "--help") for arg in sys.argv[1:]):
        return main()
    started = time.perf_counter()
    with _teed() as tee:
        result = main()
    intro = (doc or "").split("\n\n    ")[0].strip()
    output = tee.kept.getvalue().rstrip()
    write_page(name, intro, [f"```text\n{output}\n```"], time.perf_counter() - started)
    return result


def placeholder(name: str, docs: Path | None = None) -> Path:
    """The page of a benchmark that has not run here yet (only where no page exists)."""
    title, command = BENCHMARKS[name]
    path = _page_path(name, docs)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        f"# {title}\n\n{NOT_RUN} `make bench` (or `python {command}`) writes this page with "
        "its tables, the machine, the date and the command.\n",
        encoding="utf-8",
    )
    return path


def write_index(docs: Path | None = None) -> Path:
    """``docs/benchmarks/index.md``: every benchmark page, and which have numbers yet."""
    folder = PAGES if docs is None else docs
    rows = []
    for name, (title, command) in BENCHMARKS.items():
        page = folder / f"{name}.md"
        text = page.read_text(encoding="utf-8") if page.exists() else NOT_RUN
        state = "not yet run" if NOT_RUN in text else "measured"
        rows.append((f"[{title}]({name}.md)", f"`python {command}`", state))
    text = "\n\n".join(
        [
            "# Benchmarks",
            "Every page here is written by its benchmark script (`make bench` runs them all, "
            "on demand; they take from seconds to hours). Each page says the machine, the date, "
            "the Python and numpy versions and the exact command that produced its numbers; "
            "none is typed by hand. Compare ratios (times real time, RMSE over the bound) "
            "between machines, not seconds. The gate study's tables are in "
            "[the gate study](../explanation/gate-study.md), written by "
            "`benchmarks/bench_gate_study.py`.",
            markdown_table(("benchmark", "command", "numbers"), rows),
        ]
    )
    path = folder / "index.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text + "\n", encoding="utf-8")
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description="Placeholder pages and the benchmarks index.")
    parser.add_argument("--docs", type=Path, default=PAGES, help="folder of the benchmark pages")
    args = parser.parse_args()
    for name in BENCHMARKS:
        if not _page_path(name, args.docs).exists():
            print(f"wrote {placeholder(name, args.docs)}")
    print(f"wrote {write_index(args.docs)}")


if __name__ == "__main__":
    main()
