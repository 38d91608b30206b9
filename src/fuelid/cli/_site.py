"""``fuelid site …``: the site file that describes one loop as its PLC exposes it.

``fuelid site check`` reads and validates a site file and prints its tag map (or refuses it with
the key and the reason, exit code 2). The PLC link itself (``record``, ``plant serve``) builds on
the same file (issue 14).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import emit_json, guarded, provenance

if TYPE_CHECKING:
    from rich.text import Text

SCALING_WIDTH = 16
"""Least width of site check's scaling column, which wraps [characters]."""

app = typer.Typer(help="The site file: one loop as its PLC exposes it.", rich_markup_mode=None)


@app.command("check")
@guarded
def check(
    config: Annotated[
        Path,
        typer.Option("--config", "-c", metavar="SITE.toml", help="The site file to check."),
    ],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Validate a site file and show its protocol, sampling and tags with their scaling."""
    from fuelid.online import load_service_site

    site = load_service_site(config)
    if as_json:
        from fuelid.online import check_site_plant

        check_site_plant(site.site.plant, site.online.window_s)
        data: dict[str, Any] = site.model_dump() | {"missing": site.missing()}
        emit_json(data | provenance({"config": str(config)}, config))
        return
    from rich.console import Console
    from rich.table import Table

    plc = site.plc
    where = plc.endpoint or plc.path or f"{plc.host}:{plc.port or plc.default_port}"
    table = Table(
        title=f"{site.site.name}: {plc.protocol} at {where}, every {site.sampling.period_s:g} s "
        f"(PI every {site.sampling.control_period_s:g} s)"
    )
    columns = ("side", "role", "address", "type", "scaling", "unit")
    for column in columns:
        # an address (an OPC UA node id) is copied into other tools, a role or a type is
        # searched for: never cut or wrapped (the scaling, a sentence, may wrap)
        table.add_column(
            column,
            no_wrap=column != "scaling",
            min_width=SCALING_WIDTH if column == "scaling" else None,
        )
    for side, tags in (("read", site.tags), ("write", site.write)):
        for role, tag in tags.items():
            scaling = ""
            if tag.raw is not None and tag.eng is not None:
                scaling = (
                    f"{tag.raw[0]:g}…{tag.raw[1]:g} → {tag.eng[0]:g}…{tag.eng[1]:g} {tag.unit}"
                )
            table.add_row(*_cells(side, role, tag.address, tag.type, scaling, tag.unit))
    if site.ring is not None:
        ring = site.ring
        from_ring = ", ".join(ring.fields[1:])
        table.add_row(
            *_cells(
                "read",
                "ring",
                f"{ring.address} (head {ring.head})",
                f"{ring.size} × [{', '.join(ring.fields)}]",
                f"{from_ring} come from here",
                "",
            )
        )
    from fuelid.online import check_site_plant

    settling = check_site_plant(site.site.plant, site.online.window_s)
    console = Console()
    # wider than the terminal rather than a cell cut short: the terminal wraps the line (rich
    # would shrink every column to fit the terminal, ending the long ones with "…")
    whole = [
        max(len(header), *(len(cell) for cell in table.columns[i].cells))  # type: ignore[arg-type]
        for i, header in enumerate(columns)
        if header != "scaling"
    ]
    least = sum(whole) + SCALING_WIDTH + 3 * len(columns) + 1  # padding and rules
    console = Console(width=max(console.width, least))
    console.print(table)
    for line in site.missing():
        console.print(f"missing {line}", highlight=False)
    for line in _summary(site, settling):
        typer.echo(line)


def _summary(site: Any, settling: float | None) -> list[str]:
    """The plant, controller, online and test-signal lines under the tag table."""
    plant = (
        f"plant      {site.site.plant} (settling time {settling:.3g} s at mid-range, 20 °C)"
        if site.site.plant is not None
        else "plant      none: the online service tracks K per command band, no physics anchor"
    )
    c = site.controller
    if c is None:
        controller = "controller none: the online service identifies and tracks only"
    else:
        unit = "V per L/min" if c.gain_units == "engineering" else "% per % of span"
        controller = (
            f"controller {c.form} form, Kc in {unit}, Ti in {c.integral_unit}; commissioning "
            f"kc = {'-' if c.kc is None else f'{c.kc:.4g}'}, "
            f"ti = {'-' if c.ti is None else f'{c.ti:.4g}'}"
        )
    o = site.online
    online = (
        f"online     identify every {o.identify_every_s:g} s of data on the last {o.window_s:g} s, "
        f'write_back "{o.write_back}", rule {o.rule}, Ms ≤ {o.ms_target:g}'
    )
    return [plant, controller, online, _excitation_line(site)]


def _excitation_line(site: Any) -> str:
    """The test signal: its mode and limits, or why the site cannot carry one."""
    e = site.excitation
    if "excitation" not in site.write:
        return "signal     none: no [write.excitation] register (a test signal needs one)"
    if e.amplitude is None:
        return (
            "signal     off: [write.excitation] is mapped; an [excitation] table with an "
            "amplitude would use it"
        )
    margin = e.margin_to_limits if e.margin_to_limits is not None else 2.0 * e.amplitude
    wait = "one settling time" if e.wait_after_move_s is None else f"{e.wait_after_move_s:g} s"
    return (
        f'signal     mode "{e.mode}", at most ±{e.amplitude:g} V on the PI output for '
        f"{100.0 * e.max_share:g} % of a window, {margin:g} V from the drive's limits, "
        f"{wait} after a move"
    )


def _cells(*texts: str) -> list[Text]:
    """Table cells shown as written: "[seq, command]" is text, not a rich markup tag."""
    from rich.text import Text

    return [Text(text) for text in texts]
