"""``fuelid online status`` and ``history``: what the service has done, read from its store."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import check_figure_path, emit_json, guarded, provenance

if TYPE_CHECKING:
    pass

from fuelid.cli.online._app import ConfigFile, JsonFlag, StoreFile, _opened, _options, app

RECENT_WINDOWS = 20
"""Windows listed by ``fuelid online history`` without ``--json``."""
IDEAL_UNITS = {"Kc": "V per L/min", "Ti": "s"}
"""The units of the ideal-form gains (what the block holds when its form is the default)."""


def _stamp(t: float | None, tz: str | None = "UTC") -> str:
    if t is None:
        return "-"
    from fuelid.io import format_time

    return format_time(t, tz)


def _pm(values: dict[str, Any] | None, errors: dict[str, Any] | None, key: str, unit: str) -> str:
    value = (values or {}).get(key)
    if value is None:
        return f"{key} -"
    se = (errors or {}).get(key)
    text = f"{value:.4g}" + ("" if se is None else f" ± {se:.2g}")
    return f"{text} {unit}".rstrip()


def _model_text(entry: dict[str, Any]) -> str:
    model, se = entry.get("model"), entry.get("stderr")
    parts = [
        "K = " + _pm(model, se, "K", "(L/min)/V"),
        "T = " + _pm(model, se, "T", "s"),
        "θ = " + _pm(model, se, "delay", "s"),
    ]
    return ", ".join(parts)


def _gains_text(p: dict[str, Any]) -> str:
    """``#3 pending: Kc 0.8 → 0.9 %/% (target 1.0), Ti 3 → 2.8 s (target 2.6) (Ms 1.62)``.

    Units and targets when the proposal carries them (``gain_units``, ``target``).
    """
    old, new = p.get("old") or {}, p.get("new") or {}
    units = p.get("gain_units") or {}
    target = p.get("target") or {}

    def g(d: dict[str, Any], k: str) -> str:
        return "-" if d.get(k) is None else f"{d[k]:.4g}"

    def one(k: str) -> str:
        text = f"{k} {g(old, k)} → {g(new, k)}"
        if units.get(k):
            text += f" {units[k]}"
        if target.get(k) is not None:
            text += f" (target {target[k]:.4g})"
        return text

    ms = p.get("Ms")
    stale = f" — out of date, not written: {p['stale']}" if p.get("stale") else ""
    return (
        f"#{p['id']} {p['status']}: {one('Kc')}, {one('Ti')}"
        + ("" if ms is None else f" (Ms {ms:.2f})")
        + stale
    )


def _trend_text(trend: dict[str, Any]) -> str:
    if not trend.get("available"):
        return f"not yet ({trend.get('reason', '')})"
    at = trend.get("at_newest") or {}
    n = trend.get("n")
    text = f"{trend.get('mode')} fit over {n} windows"
    ratio = trend.get("ratio")
    if isinstance(ratio, dict):
        text += f", K/K_plant {ratio['intercept']:.3f} ± {ratio['se_intercept']:.2g}"
        text += f" at {ratio['T_ref']:.1f} °C"
        if ratio.get("slope") is not None:
            text += f", slope {ratio['slope']:.2e} ± {ratio['se_slope']:.1e} /°C"
    if at.get("K") is not None:
        text += (
            f"; K at {at['fuel_temperature']:.1f} °C, {at['u']:.2f} V: "
            f"{at['K']:.4g} ± {at['se']:.2g} (L/min)/V"
        )
    drift = trend.get("drift")
    if isinstance(drift, dict):
        text += f"; drift from the tuned model {drift['ratio']:.3f} ± {drift['se']:.2g}"
    return text


def status_lines(status: dict[str, Any]) -> list[str]:
    """The human form of :func:`~fuelid.online._report.status_json`, a few aligned lines."""
    from fuelid.online import (  # numpy behind it: not at `fuelid --help`
        health_line,
        held_line,
        write_times_text,
    )
    from fuelid.online.excitation import excitation_line

    tz = status.get("timezone") or "UTC"
    link = status["link"]
    link_text = _link_text(link, tz)
    w = status.get("last_window")
    if w is None:
        window_text = "none yet"
    else:
        verdict = "accepted" if w["accepted"] else "rejected"
        fuel = w.get("fuel_temperature")
        window_text = (
            f"#{w['id']} ending {_stamp(w['end'], tz)}, {w.get('mode') or '-'}, "
            + ("" if fuel is None else f"fuel {fuel:.1f} °C, ")
            + f"{verdict}: {w['reason']}"
        )
    m = status.get("current_model")
    if m is None:
        model_text = "none accepted yet"
    else:
        fuel = m.get("fuel_temperature")
        model_text = (
            _model_text(m)
            + f" (window ending {_stamp(m.get('end'), tz)}"
            + ("" if fuel is None else f", fuel {fuel:.1f} °C")
            + ")"
        )
    pending = status.get("pending_proposals") or []
    proposals_text = (
        "; ".join(_gains_text(p) for p in pending)
        if pending
        else held_line(status.get("held_proposal")) or "none"
    )
    wb = status.get("write_back") or {}
    last_write = status.get("last_write")
    write_text = f"write_back {wb.get('setting') or 'unknown (give --config)'}"
    if wb.get("setting_from") == "service":
        running = (status.get("service") or {}).get("state") == "running"
        write_text += (
            " (from the running service's settings)"
            if running
            else " (from the last service's settings)"
        )
    if wb.get("write_held"):
        write_text += f", held: {wb['write_held']}"
    if wb.get("revert_requested"):
        write_text += ", revert requested"
    write_text += "; last write " + (
        "none"
        if last_write is None
        else f"#{last_write['id']} {last_write['kind']} {last_write['status']} "
        f"(Kc {last_write['Kc']:.4g}, Ti {last_write['Ti']:.4g}): "
        f"{write_times_text(last_write, tz)}"
    )
    c = status.get("counts") or {}
    last = status.get("last_window") or {}
    step = last.get("step_ls") or {}
    step_text = (
        "-"
        if not step
        else (
            _model_text(step)
            if step.get("model")
            else f"not fitted: {step.get('reason', 'no reason given')}"
        )
        + " (the article's method, reported beside, not gated)"
    )
    rows = [
        ("site", f"{status['site']['name']} (store {status['site']['store']})"),
        ("link", link_text),
        ("window", window_text),
        ("model", model_text),
        ("step-ls", step_text),
        ("K(T)", _trend_text(status.get("k_trend") or {})),
        ("proposals", proposals_text),
        ("requests", _requests_text(status.get("requests") or [])),
        ("health", health_line(status.get("loop_health"))),
        *[("signal", line) for line in [excitation_line(status.get("excitation"))] if line],
        *_plc_gains_rows(status.get("plc_gains"), tz),
        ("writes", write_text),
        (
            "counts",
            f"{c.get('windows', 0)} windows, {c.get('accepted', 0)} accepted, "
            f"{c.get('proposals', 0)} proposals, {c.get('writes', 0)} writes",
        ),
    ]
    central = status.get("central")
    if central and (central.get("outbox") == "on" or central.get("last_ok")):
        rows.append(("central", _central_text(central, tz)))
    return [f"{name:<10} {text}" for name, text in rows]


def _plc_gains_rows(gains: dict[str, Any] | None, tz: str) -> list[tuple[str, str]]:
    """``PLC gains  Kc 1.25 %/%, Ti 0.5 min (ideal Kc 0.05 V per L/min, Ti 30 s), read at …``.

    No row when the status has none (no kc and ti tags, or nothing read yet).
    """
    if not gains:
        return []
    units = gains.get("units") or {}

    def pair(g: dict[str, Any], u: dict[str, Any]) -> str:
        return ", ".join(
            f"{key} {g[key]:.4g} {u.get(key) or ''}".rstrip()
            for key in ("Kc", "Ti")
            if g.get(key) is not None
        )

    text = pair(gains, units)
    ideal = gains.get("ideal")
    if ideal and units != IDEAL_UNITS:
        text += f" (ideal {pair(ideal, IDEAL_UNITS)})"
    return [("PLC gains", f"{text}, read at {_stamp(gains.get('time'), tz)} (the kc, ti tags)")]


def _central_text(central: dict[str, Any], tz: str) -> str:
    """``backlog 12 rows (oldest 4 s ago), last send …, last error …``."""
    from fuelid.io import format_age

    age = central.get("backlog_age_s")
    text = f"backlog {central.get('backlog_rows', 0)} rows" + (
        "" if age is None else f" (oldest {format_age(age)} ago)"
    )
    last_ok = central.get("last_ok")
    text += ", last send " + ("never" if last_ok is None else _stamp(last_ok, tz))
    if central.get("failing_since") is not None:
        text += (
            f", failing since {_stamp(central['failing_since'], tz)}: {central.get('last_error')}"
        )
    return text


def _link_text(link: dict[str, Any], tz: str) -> str:
    """``service stopped (no beat for …)``, ``up (newest sample 0.6 s ago; plant time …)``."""
    text = str(link.get("text") or link.get("state"))
    plant = link.get("newest_sample")
    if link.get("state") in ("up", "link_down") and plant is not None:
        text = text[:-1] + f"; plant time {_stamp(plant, tz)})" if text.endswith(")") else text
    return text


def _requests_text(requests: list[dict[str, Any]]) -> str:
    if not requests:
        return "none waiting"
    return "; ".join(
        f"#{r['id']} {r['kind']}"
        + ("" if r.get("proposal_id") is None else f" #{r['proposal_id']}")
        + f" by {r['who']} ({r['origin']}), waiting"
        for r in requests
    )


@app.command("status")
@guarded
def status_command(
    config: ConfigFile = None, store: StoreFile = None, as_json: JsonFlag = False
) -> None:
    """Link, last window and its verdict, current model, K(T) trend, proposals, loop health.

    Read from the store; a running service need not be stopped. The link line says whether the
    service runs (its beat, on the wall clock) and the link is up; times in the site's time zone.
    --json prints one object (keys site, link, service, timezone, last_window, current_model,
    k_trend, pending_proposals, requests, loop_health, counts, write_back, last_write, central,
    units).
    """
    from fuelid.online import status_json

    with _opened(config, store) as (opened, history, settings):
        status = status_json(history, opened, settings=settings)
    if as_json:
        emit_json(status | provenance(_options(config, store)))
        return
    typer.echo("\n".join(status_lines(status)))


@app.command("history")
@guarded
def history_command(
    config: ConfigFile = None,
    store: StoreFile = None,
    as_json: JsonFlag = False,
    plot: Annotated[
        Path | None,
        typer.Option(
            "--plot",
            metavar="FILE.png",
            help="Draw K over time and against fuel temperature with 95 % intervals, the gains "
            "and the proposals.",
            show_default=False,
        ),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing --plot.")] = False,
) -> None:
    """Every window, proposal, event and write of the service, oldest first.

    --json prints one object with windows (start, end, accepted, reason, fuel_temperature,
    model, stderr, ci95 as fuelid identify's), proposals (id, time, status, old, new, Ms, reason,
    history), events, writes, k_trend.
    """
    from fuelid.online import history_json, write_times_text

    check_figure_path(plot, overwrite=force)
    with _opened(config, store) as (opened, history, settings):
        data = history_json(history, opened, settings=settings)
    if plot is not None:
        from fuelid.plots import plot_online_history

        plot_online_history(data, plot)
    if as_json:
        emit_json(data | provenance(_options(config, store, plot=plot and str(plot))))
        return
    windows = data["windows"]
    tz = data.get("timezone") or "UTC"
    units = data.get("gain_units") or {}
    for p in data["proposals"]:
        p.setdefault("gain_units", units or None)
    lines = [f"{len(windows)} windows, {sum(w['accepted'] for w in windows)} accepted"]
    if len(windows) > RECENT_WINDOWS:
        lines.append(f"(the newest {RECENT_WINDOWS}; --json for all)")
    for w in windows[-RECENT_WINDOWS:]:
        fitted = "" if w.get("model") is None else " " + _model_text(w)
        fuel = w.get("fuel_temperature")
        lines.append(
            f"  #{w['id']:<5} {_stamp(w['end'], tz)} {'ok ' if w['accepted'] else 'no '}"
            + ("" if fuel is None else f"{fuel:6.1f} °C")
            + f"{fitted} | {w['reason']}"
        )
    lines.append(f"{len(data['proposals'])} proposals")
    lines += [f"  {_gains_text(p)} at {_stamp(p['time'], tz)}" for p in data["proposals"]]
    kinds: dict[str, int] = {}
    for e in data["events"]:
        kinds[e["kind"]] = kinds.get(e["kind"], 0) + 1
    lines.append(
        f"{len(data['events'])} events"
        + ("" if not kinds else ": " + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())))
    )
    lines.append(f"{len(data['writes'])} writes")
    lines += [
        f"  #{w['id']} {w['kind']} {w['status']} Kc {w['Kc']:.4g} Ti {w['Ti']:.4g} by {w['who']}: "
        + write_times_text(w, tz)
        for w in data["writes"]
    ]
    if plot is not None:
        lines.append(f"figure: {plot}")
    typer.echo("\n".join(lines))
