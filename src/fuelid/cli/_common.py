"""What every command shares: error handling at the edge, JSON output, provenance, units, options.

Only the standard library, typer and fuelid's light foundation (errors, units) are imported here
and at the top of every command module, so ``fuelid --help`` and each command's ``--help`` start
without numpy, pandas, scipy, python-control or matplotlib; a command imports the library inside
its body, when it runs (docs/explanation/architecture.md, "Rules"). °C, L/min and V live here at the
edge: the library gets kelvin.
"""

from __future__ import annotations

import enum
import functools
import hashlib
import json
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ParamSpec, TypeVar

import typer

from fuelid import __version__
from fuelid.errors import FuelidError
from fuelid.io.jsonsafe import json_ready
from fuelid.units import celsius_to_kelvin

if TYPE_CHECKING:
    from fuelid.io.timeseries import IOData

P = ParamSpec("P")
R = TypeVar("R")

EXIT_BAD_INPUT = 2


def fail(message: str) -> typer.Exit:
    """Print a one-line reason on stderr and return the exit for bad input (code 2)."""
    one_line = " ".join(str(message).split())
    typer.echo(f"error: {one_line}", err=True)
    return typer.Exit(EXIT_BAD_INPUT)


FIGURE_FORMATS = ("png", "svg", "pdf")


def check_figure_path(path: Path | None, overwrite: bool = False) -> None:
    """Refuse a figure path that cannot be written, before any work is done.

    An existing file is refused unless ``overwrite`` (``--force``): every command that writes a
    figure follows the one rule of ``fuelid simulate`` and ``fuelid report``.
    """
    if path is None:
        return
    if path.is_dir():
        raise FuelidError(f"figure path {str(path)!r} is a folder; give a file name")
    if not path.parent.is_dir():
        raise FuelidError(f"figure folder {str(path.parent)!r} does not exist")
    if path.suffix.lower().lstrip(".") not in FIGURE_FORMATS:
        raise FuelidError(
            f"figure {str(path)!r}: name it .png, .svg or .pdf (the suffix picks the format)"
        )
    if path.exists() and not overwrite:
        raise FuelidError(f"figure {str(path)!r} exists; pass --force to replace it")


def guarded(command: Callable[P, R]) -> Callable[P, R]:
    """Run a command with BLAS on one thread; every :class:`FuelidError` becomes exit 2.

    The whole command runs inside :func:`fuelid.blas.single_threaded_blas`: its sweeps and checks
    are many small matrices, which a multi-threaded BLAS on a loaded two-core machine runs many
    times slower. numpy and scipy's linear algebra are loaded first, so that the BLAS libraries
    they bring (numpy's and scipy's own) are both found and pinned. Imported here, when a command
    runs, so ``--help`` loads no numerical library.
    """

    @functools.wraps(command)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        import numpy  # noqa: F401  (loads numpy's BLAS before the thread limit is set)
        import scipy.linalg  # noqa: F401  (and scipy's own BLAS)

        from fuelid.blas import single_threaded_blas

        try:
            with single_threaded_blas():
                return command(*args, **kwargs)
        except FuelidError as exc:
            raise fail(str(exc)) from None

    return wrapper


def emit_json(payload: dict[str, Any]) -> None:
    """Print exactly one JSON object on stdout."""
    sys.stdout.write(json.dumps(json_ready(payload), indent=2, allow_nan=False) + "\n")


def warn(message: str) -> None:
    """A warning on stderr (never on stdout, which may carry JSON)."""
    typer.echo(f"warning: {message}", err=True)


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (provenance of results)."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def format_estimate(value: float, stderr: float | None, minimum: int = 5) -> str:
    """A number with the digits its standard error justifies: down to the error's second digit.

    >>> format_estimate(0.99998, 2.6e-05), format_estimate(0.99998, None)
    ('0.999980', '0.99998')
    >>> format_estimate(10.9987, 0.0018), format_estimate(13.2807, 0.0003)
    ('10.9987', '13.28070')
    >>> format_estimate(8.99, 0.0054), format_estimate(9.0119, 0.0054), format_estimate(12345.6, 80)
    ('8.9900', '9.0119', '12346')
    """
    if stderr is None or not (stderr > 0.0 and math.isfinite(stderr)) or value == 0.0:
        return f"{value:.{minimum}g}"
    if not math.isfinite(value):
        return str(value)
    digits = math.floor(math.log10(abs(value))) - math.floor(math.log10(stderr)) + 2
    # trailing zeros kept, so an estimate and its interval's ends show the same places
    text = f"{value:#.{min(max(digits, minimum), 17)}g}"
    return text.rstrip(".")


def format_interval(low: float, high: float, minimum: int = 3) -> str:
    """An interval ``low … high`` with the digits its width needs: the width to 2 digits.

    Each end gets at least ``minimum`` significant digits and as many more as it takes to show
    the interval's width (high − low) to two significant digits, so two ends that differ by
    more than rounding never print alike (a 95 % interval of 21.0004 ± 1.96 · 0.0002 is not
    "21 … 21").

    >>> format_interval(21.0004 - 1.96 * 0.0002, 21.0004 + 1.96 * 0.0002)
    '21.00001 … 21.00079'
    >>> format_interval(20.8, 21.2), format_interval(0.5, 0.5), format_interval(-1.0, 1e6)
    ('20.80 … 21.20', '0.5 … 0.5', '-1.00 … 1.00e+06')
    """
    width = high - low
    largest = max(abs(low), abs(high))
    if not (math.isfinite(width) and width > 0.0 and largest > 0.0):
        return f"{low:.{minimum}g} … {high:.{minimum}g}"
    digits = math.floor(math.log10(largest)) - math.floor(math.log10(width)) + 2
    spec = f"#.{min(max(digits, minimum), 17)}g"
    return f"{format(low, spec).rstrip('.')} … {format(high, spec).rstrip('.')}"


def provenance(options: dict[str, Any], input_file: Path | None = None) -> dict[str, Any]:
    """The provenance block every JSON result carries."""
    return {
        "fuelid_version": __version__,
        "input_sha256": file_sha256(input_file) if input_file is not None else None,
        "options": options,
    }


def checked_kelvin(t_degC: float, name: str = "fuel temperature") -> float:
    """An option's temperature [°C], refused unless finite, in SI [K] (``celsius_to_kelvin``)."""
    if not math.isfinite(t_degC):
        raise FuelidError(f"{name} must be a finite temperature, got {t_degC}")
    return celsius_to_kelvin(t_degC)


@dataclass(frozen=True)
class SiteFacts:
    """What ``--site`` gives tune and report: the PI period and the block's spans and form."""

    control_period: float | None
    """``[sampling] control_period_s`` [s] when the file sets it (its default is not a fact)."""
    spans: tuple[float | None, float | None]
    """``[controller]`` u_span_V [V] and y_span_Lpm [L/min]."""
    controller: Any
    """The site's :class:`fuelid.plc.site.Controller`, or None."""
    plant: Path | None = None
    """The site's ``[site] plant`` (taken from the site file's folder), or None."""
    timezone: str | None = None
    """``[site] timezone`` when the file sets it: the zone of a log's stamps without offsets."""


def site_facts(path: Path | None) -> SiteFacts | None:
    """Read ``--site``: the control period it sets and its controller block (None: no file)."""
    if path is None:
        return None
    from fuelid.online import load_service_site

    site = load_service_site(path)
    sampling = site.sampling
    period = sampling.control_period_s if "control_period_s" in sampling.model_fields_set else None
    controller = site.controller
    spans = (None, None) if controller is None else (controller.u_span_V, controller.y_span_Lpm)
    plant = None if site.site.plant is None else Path(site.site.plant)
    zone = site.site.timezone if "timezone" in site.site.model_fields_set else None
    return SiteFacts(
        control_period=period, spans=spans, controller=controller, plant=plant, timezone=zone
    )


def temperature_options(
    fuel_temp: float, t_min: float, t_max: float
) -> tuple[float, tuple[float, float]]:
    """``--fuel-temp``, ``--t-min``, ``--t-max`` [°C] checked and converted to kelvin.

    Returns
    -------
    (T_fuel, (T_min, T_max)) : float, (float, float)
        [K]
    """
    T_fuel = checked_kelvin(fuel_temp, "--fuel-temp")
    T_min = checked_kelvin(t_min, "--t-min")
    T_max = checked_kelvin(t_max, "--t-max")
    if not t_min < t_max:
        raise FuelidError(
            f"--t-min must be below --t-max (a range needs low < high), got {t_min:g} and "
            f"{t_max:g} °C"
        )
    return T_fuel, (T_min, T_max)


class RuleChoice(enum.StrEnum):
    """Tuning rules of ``fuelid tune`` (the keys of ``fuelid.tuning.TUNING_RULES``)."""

    simc = "simc"
    isimc = "isimc"
    lambda_ = "lambda"
    amigo = "amigo"


def closed_loop_time(rule: RuleChoice, tau_c: float | None, lam: float | None) -> float | None:
    """The rule's closed-loop time [s] from ``--tau-c`` or ``--lambda``, refusing a mismatch.

    τc (SIMC, improved SIMC) and λ (lambda) are the desired closed-loop time constant: larger is
    slower and more robust. None leaves the rule's default.
    """
    if tau_c is not None and lam is not None:
        raise FuelidError("give --tau-c (SIMC) or --lambda (lambda rule), not both")
    if tau_c is not None and rule not in (RuleChoice.simc, RuleChoice.isimc):
        raise FuelidError(f"--tau-c belongs to the simc and isimc rules, not {rule.value}")
    if lam is not None and rule is not RuleChoice.lambda_:
        raise FuelidError(f"--lambda belongs to the lambda rule, not {rule.value}")
    return tau_c if tau_c is not None else lam


# the options fuelid tune and fuelid report share
RuleOption = Annotated[
    RuleChoice,
    typer.Option(
        help="simc (Skogestad), isimc (improved SIMC), lambda (IMC-PI), amigo "
        "(Åström-Hägglund); see fuelid tune --list-rules."
    ),
]
TauCOption = Annotated[
    float | None,
    typer.Option(
        "--tau-c",
        help="SIMC closed-loop time constant τc [s]; larger is slower and more robust "
        "(default: θ).",
        show_default=False,
    ),
]
LambdaOption = Annotated[
    float | None,
    typer.Option(
        "--lambda",
        help="Lambda-rule closed-loop time constant λ [s]; larger is slower and more robust "
        "(default: T1).",
        show_default=False,
    ),
]
ControlPeriodOption = Annotated[
    float | None,
    typer.Option(
        metavar="SECONDS",
        help="How often the PLC runs its PI, h [s]; 0 for a continuous controller (no default: "
        "else --site's [sampling] control_period_s, or the model file's identify run).",
        show_default=False,
    ),
]
SiteOption = Annotated[
    Path | None,
    typer.Option(
        "--site",
        metavar="SITE.toml",
        help="Your site file: its [controller] (the block's form, units and spans) and its "
        "[sampling] control_period_s, when set (see the site-file reference).",
        show_default=False,
    ),
]
AcceptUndeterminedOption = Annotated[
    bool,
    typer.Option(
        "--accept-undetermined",
        help="Tune a model whose K, T or dead time the log does not determine (95 % interval "
        "unbounded or wider than the value): refused otherwise; every output then says so.",
    ),
]
TMinOption = Annotated[float, typer.Option(help="Coldest fuel [°C].")]
TMaxOption = Annotated[float, typer.Option(help="Warmest fuel [°C].")]
BandWidthOption = Annotated[float, typer.Option(help="Temperature band of the schedule [°C].")]
MsTargetOption = Annotated[
    float, typer.Option(help="Largest Ms the schedule accepts in any band [-].")
]
FlowBandsOption = Annotated[
    int, typer.Option(help="Flow bands where the gain depends on the flow (1: none).")
]
ConfigOption = Annotated[
    Path | None,
    typer.Option(
        "--config",
        "-c",
        metavar="PLANT.toml",
        help="Plant TOML file (default: the packaged reference plant).",
        show_default=False,
    ),
]


FlowSpanOption = Annotated[
    float | None,
    typer.Option(
        "--flow-span",
        metavar="L/MIN",
        help="Flowmeter span for the %/% gain [L/min] (default: the plant's meter span).",
        show_default=False,
    ),
]
DriveSpanOption = Annotated[
    float | None,
    typer.Option(
        "--u-span",
        metavar="V",
        help="Drive signal span for the %/% gain [V] (default: the plant's drive range).",
        show_default=False,
    ),
]


def check_spans(flow_span: float | None, u_span: float | None) -> None:
    """Refuse a ``--flow-span`` or ``--u-span`` that is not a positive number."""
    for option, value, unit in (("--flow-span", flow_span, "L/min"), ("--u-span", u_span, "V")):
        if value is not None and not (math.isfinite(value) and value > 0.0):
            raise FuelidError(f"{option} must be positive, got {value:g} {unit}")


def fitted_part(
    log: tuple[float, float], fitted: tuple[float, float], validated_on: str | None
) -> str:
    """The first line of ``identify`` and ``report``: the part of the log the model was fitted on.

    ``log`` and ``fitted`` are (start, end) times [s]; ``validated_on`` says what the model was
    scored on besides (None: nothing).

    >>> fitted_part((0.0, 600.0), (0.0, 420.0), "the rest")
    'fitted on 0–70 % of the log (0–420 s), validated on the rest'
    >>> fitted_part((0.0, 600.0), (0.0, 600.0), None)
    'fitted on all of the log (0–600 s), nothing held out for validation'
    """
    length = log[1] - log[0]
    if abs(fitted[0] - log[0]) <= 1e-9 * length and abs(fitted[1] - log[1]) <= 1e-9 * length:
        part = "all of the log"
    else:
        low, high = ((t - log[0]) / length * 100.0 for t in fitted)
        part = f"{low:.0f}–{high:.0f} % of the log"
    validated = (
        "nothing held out for validation"
        if validated_on is None
        else (f"validated on {validated_on}")
    )
    return f"fitted on {part} ({fitted[0]:.6g}–{fitted[1]:.6g} s), {validated}"


ForceFigureOption = Annotated[
    bool,
    typer.Option("--force", help="Overwrite an existing --plot figure (otherwise refused)."),
]
"""``--force`` of the commands whose only file written is the ``--plot`` figure."""


# the options every command that reads a PLC log shares (identify, report)
TimeColumn = Annotated[str, typer.Option(metavar="COLUMN", help="Time column (s or date-time).")]
InputColumn = Annotated[str, typer.Option(metavar="COLUMN", help="Input column.")]
OutputColumn = Annotated[str, typer.Option(metavar="COLUMN", help="Output column.")]
SampleTime = Annotated[
    float | None,
    typer.Option(
        metavar="SECONDS",
        help="Sample time [s] of a log without a time column; with one it must agree with it "
        "(1 %), and the time column is used.",
        show_default=False,
    ),
]
FillGaps = Annotated[
    float | None,
    typer.Option(
        "--fill-gaps",
        metavar="SECONDS",
        help="Bridge gaps up to this long [s] (y interpolated linearly, u held), at most 5 sample "
        "periods; longer gaps split the log into segments, identified jointly.",
        show_default=False,
    ),
]
MaxGap = Annotated[
    float | None,
    typer.Option(
        "--max-gap",
        metavar="SECONDS",
        help="An interval longer than this [s] is a gap whatever the time stamps around it "
        "(default: 3 median intervals; more than 1.1); missing samples are gaps anyway.",
        show_default=False,
    ),
]
FuelTemperatureColumn = Annotated[
    str,
    typer.Option(
        "--fuel-temp-col",
        metavar="COLUMN",
        help="Fuel temperature column [°C], read when present (another name must exist).",
    ),
]
BadValues = Annotated[
    str | None,
    typer.Option(
        "--bad-values",
        metavar="TEXT[,TEXT...]",
        help="Texts your historian writes for a bad sample, besides #N/A, Bad Input, Bad, "
        "I/O Timeout, Comm Fail, Shutdown, NaN and empty cells (case and spaces ignored): such "
        "a sample is missing (a gap), counted in the notes; other text is refused.",
        show_default=False,
    ),
]
FlowUnit = Annotated[
    str | None,
    typer.Option(
        "--flow-unit",
        metavar="UNIT",
        help="Unit of the flow column when its name does not say it (q_Lpm, 'F [L/min]'), "
        "e.g. L/min: the gains are per L/min.",
        show_default=False,
    ),
]
TimeZoneOption = Annotated[
    str | None,
    typer.Option(
        "--timezone",
        metavar="ZONE",
        help="IANA time zone of date-time stamps written without a UTC offset (local time), "
        "e.g. Europe/Berlin: converted to UTC through the clock changes. Stamps with offsets "
        "need none.",
        show_default=False,
    ),
]
TimeFormatOption = Annotated[
    str | None,
    typer.Option(
        "--time-format",
        metavar="CODES",
        help="strptime codes of the date-time stamps when fuelid does not guess their form, "
        "e.g. '%d-%b-%y %H:%M:%S' for 28-Mar-26 01:58:30.",
        show_default=False,
    ),
]
SkipRowsOption = Annotated[
    int | None,
    typer.Option(
        "--skip-rows",
        metavar="N",
        help="Lines above the header (an export's preamble); by default the header is the "
        "first line naming the time, input and output columns.",
        show_default=False,
    ),
]
InputScale = Annotated[
    str | None,
    typer.Option(
        metavar="LO:HI:LO:HI",
        help="Linear scaling raw_lo:raw_hi:eng_lo:eng_hi of the input, e.g. 4:20:1:5 for 4-20 mA "
        "to 1-5 V.",
        show_default=False,
    ),
]
OutputScale = Annotated[
    str | None,
    typer.Option(
        metavar="LO:HI:LO:HI",
        help="Linear scaling of the output, e.g. 0:27648:0:100 for counts to L/min.",
        show_default=False,
    ),
]


def read_log(
    path: Path,
    time_col: str,
    input_col: str,
    output_col: str,
    sample_time: float | None,
    input_scale: str | None,
    output_scale: str | None,
    *,
    fuel_temperature_col: str | None = "T_fuel_degC",
    fill_gaps: float | None = None,
    max_gap: float | None = None,
    bad_values: str | None = None,
    flow_unit: str | None = None,
    progress: Callable[[str], None] | None = None,
    timezone: str | None = None,
    time_format: str | None = None,
    skip_rows: int | None = None,
) -> IOData:
    """Load a log with the shared column, scaling, gap and bad-value options.

    A sample time replaces a missing time column; with a time column present the two must agree
    and the time column is used (so that gaps are seen). An empty ``fuel_temperature_col`` reads
    no fuel temperature. ``bad_values`` is ``--bad-values``' comma-separated text.
    """
    from fuelid.io import parse_bad_values
    from fuelid.io.logs import load_log
    from fuelid.io.tables import parse_scale

    return load_log(
        path,
        time_col=time_col,
        input_col=input_col,
        output_col=output_col,
        sample_time=sample_time,
        input_scale=parse_scale(input_scale) if input_scale else None,
        output_scale=parse_scale(output_scale) if output_scale else None,
        fill_gaps=fill_gaps,
        max_gap=max_gap,
        fuel_temperature_col=fuel_temperature_col or None,
        bad_values=parse_bad_values(bad_values),
        output_unit=flow_unit.strip() if flow_unit and flow_unit.strip() else None,
        progress=progress,
        timezone=timezone.strip() if timezone and timezone.strip() else None,
        time_format=time_format or None,
        skip_rows=skip_rows,
    )


@dataclass(frozen=True)
class LogReadOptions:
    """The log-reading options of ``identify`` and ``report``, gathered once per command.

    Each field is the option of the same name (``--time-col``, ``--fuel-temp-col``, ...) as
    given. :meth:`read` loads a log with them (:func:`read_log`), :meth:`to_json` is their part
    of the provenance's ``options``.
    """

    time_col: str = "t_s"
    input_col: str = "u_V"
    output_col: str = "q_Lpm"
    sample_time: float | None = None
    input_scale: str | None = None
    output_scale: str | None = None
    fuel_temp_col: str = "T_fuel_degC"
    fill_gaps: float | None = None
    max_gap: float | None = None
    bad_values: str | None = None
    flow_unit: str | None = None
    timezone: str | None = None
    time_format: str | None = None
    skip_rows: int | None = None

    def read(self, path: Path, progress: Callable[[str], None] | None = None) -> IOData:
        """The log at ``path``, read with these options; ``progress`` is told each stage."""
        return read_log(
            path,
            self.time_col,
            self.input_col,
            self.output_col,
            self.sample_time,
            self.input_scale,
            self.output_scale,
            fuel_temperature_col=self.fuel_temp_col,
            fill_gaps=self.fill_gaps,
            max_gap=self.max_gap,
            bad_values=self.bad_values,
            flow_unit=self.flow_unit,
            timezone=self.timezone,
            time_format=self.time_format,
            skip_rows=self.skip_rows,
            progress=progress,
        )

    def to_json(self) -> dict[str, Any]:
        """The options as the JSON's provenance records them (in 0.2.0's keys and order).

        ``timezone``, ``time_format`` and ``skip_rows`` are not among them, as in 0.2.0.
        """
        return {
            "time_col": self.time_col,
            "input_col": self.input_col,
            "output_col": self.output_col,
            "sample_time": self.sample_time,
            "input_scale": self.input_scale,
            "output_scale": self.output_scale,
            "fuel_temp_col": self.fuel_temp_col,
            "fill_gaps": self.fill_gaps,
            "max_gap": self.max_gap,
            "bad_values": self.bad_values,
            "flow_unit": self.flow_unit,
        }


def flow_unit_warning(data: IOData, output_col: str) -> str | None:
    """The warning for a flow column whose unit nothing says (its name, a units row, an option).

    The gains are per L/min; a flow in another unit gives gains off by the ratio, so the user is
    asked for the unit rather than shown a gain per "(output unit)".
    """
    if data.y_unit:
        return None
    return (
        f"flow column {output_col!r} has no unit: give --flow-unit (e.g. --flow-unit L/min), or "
        f"name the column with its unit (q_Lpm, '{output_col} [L/min]'); the PI gains take the "
        "flow as L/min"
    )


@contextmanager
def progress_display(
    quiet: bool = False, *, console: Any = None, show_after: float | None = None
) -> Iterator[Callable[[str], None]]:
    """A line on stderr with the current stage, its bar (steps known) or spinner, and its time.

    Shown only when stderr is a terminal and not ``quiet`` (``--quiet``), once a stage has run
    a moment (:mod:`fuelid.cli._progress`), and gone when the block ends, so stdout (the JSON
    of ``--json``) and a redirected stderr see nothing of it. Yields the workflow's
    ``progress`` callback (:mod:`fuelid.workflow._progress`), which also takes a stage's steps.
    ``console`` (a rich console, for tests) and ``show_after`` [s] replace the defaults.
    """
    from rich.console import Console

    console = Console(stderr=True) if console is None else console
    if quiet or not console.is_terminal:
        yield lambda stage: None
        return
    from fuelid.cli._progress import SHOW_AFTER, stage_bar

    display, stage = stage_bar(console, SHOW_AFTER if show_after is None else show_after)
    with display:
        yield stage
