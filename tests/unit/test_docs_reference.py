"""The Reference pages say what the program does: cheap checks that `make test` runs.

- every key a command prints with ``--json`` is explained in docs/reference/json.md (the site
  file's keys in site-file.md), run on the reference plant;
- every command and option reaches the generated command page (the page's Markdown is built by
  the site's own hook, docs/hooks/cli_reference.py, without building the site);
- every page of the nav exists, every page is in the nav, and every relative link in docs/
  points at a file that exists: what ``mkdocs build --strict`` (``make docs``) would refuse.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import json
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from fuelid.cli import main
from fuelid.store import Sample, SQLiteStore

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
REFERENCE = DOCS / "reference"
PLANT_FILE = ROOT / "src" / "fuelid" / "data" / "reference_plant.toml"


def load_hook() -> ModuleType:
    """docs/hooks/cli_reference.py, imported by path (it is the site's code, not a package)."""
    path = DOCS / "hooks" / "cli_reference.py"
    spec = importlib.util.spec_from_file_location("fuelid_docs_cli_reference", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


# --- (a) every JSON key is explained ------------------------------------------------------------


def key_names(data: Any, skip: frozenset[str] = frozenset()) -> Iterator[str]:
    """Every key name in a JSON value, except below keys named in ``skip``.

    Below ``options`` are the command's own option names (explained once, in the command page);
    below ``units`` the names of the other keys; numeric keys are data (the order in ``aic``).
    """
    if isinstance(data, dict):
        for key, value in data.items():
            if not key.isdigit():
                yield key
            if key not in skip:
                yield from key_names(value, skip)
    elif isinstance(data, list):
        for item in data:
            yield from key_names(item, skip)


def documented_names(*pages: Path) -> set[str]:
    """Every identifier inside a code span of the pages (`a.b` gives a and b)."""
    names: set[str] = set()
    for page in pages:
        # fenced blocks first: their backticks would pair with the spans' and hide them
        text = re.sub(
            r"^\s*(```|~~~).*?^\s*\1",
            "",
            page.read_text(encoding="utf-8"),
            flags=re.DOTALL | re.MULTILINE,
        )
        for span in re.findall(r"`([^`]+)`", text):
            names.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", span))
    return names


@pytest.fixture(scope="module")
def json_outputs(
    tmp_path_factory: pytest.TempPathFactory,
) -> dict[str, dict[str, Any]]:
    """The JSON of the commands that run in seconds, on the reference plant's data."""
    outputs: dict[str, dict[str, Any]] = {}
    folder = tmp_path_factory.mktemp("json")
    log, ident = folder / "log.csv", folder / "ident.json"
    site, store = folder / "site.toml", folder / "store.db"

    # capsys is function-scoped: the module's one run of each command captures its own output
    def run(*argv: str) -> dict[str, Any]:
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([*argv, "--json"])
        assert code == 0, err.getvalue()
        data = json.loads(out.getvalue())
        assert isinstance(data, dict)
        return data

    outputs["plant info"] = run("plant", "info", "--u", "2")
    outputs["simulate"] = run(
        "simulate", str(log), "--profile", "steps", "--levels", "2,3,2.5,3.5",
        "--dwell", "20", "--seed", "1", "--pressure",
    )  # fmt: skip
    # the PLC period is never assumed (issue 37): identify records it for tune
    outputs["identify"] = run(
        "identify", str(log), "--validate-split", "0.3", "--control-period", "1"
    )
    ident.write_text(json.dumps(outputs["identify"]), encoding="utf-8")
    # without a plant file: the range check on the log's command bands, no %/% gains
    outputs["tune"] = run("tune", "--model", str(ident))
    # with the user's plant file (the packaged one, given as theirs): the temperature check and
    # the %/% gains on its spans, the keys tune prints only then
    outputs["tune --config"] = run("tune", "--model", str(ident), "--config", str(PLANT_FILE))
    outputs["tune --schedule"] = run(
        "tune", "--model", str(ident), "--schedule", "--band-width", "35", "--flow-bands", "1",
        "--config", str(PLANT_FILE),
    )  # fmt: skip
    site.write_text(
        '[site]\nname = "docs"\n[plc]\nprotocol = "replay"\npath = "log.csv"\n'
        '[sampling]\nperiod_s = 0.02\n[tags.command]\naddress = "u_V"\nunit = "V"\n'
        '[tags.flow]\naddress = "q_Lpm"\nunit = "L/min"\n',
        encoding="utf-8",
    )
    outputs["site check"] = run("site", "check", "--config", str(site))
    with SQLiteStore(store, site_name="docs", tag_map_hash="ab12") as db:
        db.append_samples([Sample(1.7e9 + 0.02 * k, k, 2.0, 40.0) for k in range(50)])
    outputs["store info"] = run("store", "info", "--store", str(store))
    return outputs


@pytest.mark.parametrize(
    "command",
    [
        "plant info",
        "simulate",
        "identify",
        "tune",
        "tune --config",
        "tune --schedule",
        "site check",
        "store info",
    ],
)
def test_every_json_key_is_explained_in_the_reference(
    json_outputs: dict[str, dict[str, Any]], command: str
) -> None:
    pages = [REFERENCE / "json.md"]
    if command == "site check":  # the site file as read: its keys are the site file's
        pages.append(REFERENCE / "site-file.md")
    documented = documented_names(*pages)
    keys = set(key_names(json_outputs[command], frozenset({"options", "units"})))
    missing = sorted(keys - documented)
    assert not missing, (
        f"`fuelid {command} --json` keys not in {[p.name for p in pages]}: {missing}"
    )


def test_key_names_skip_option_names_and_data_keys() -> None:
    data = {"a": {"b": 1}, "options": {"time_col": "t"}, "aic": {"1": 2.0}, "l": [{"c": 0}]}
    assert sorted(key_names(data, frozenset({"options"}))) == ["a", "aic", "b", "c", "l", "options"]


# --- (b) every command and option reaches the generated page -------------------------------------


def test_every_command_and_option_is_in_the_generated_command_page() -> None:
    hook = load_hook()
    page = hook.render_cli_reference()
    sections = re.split(r"^#{2,4} ", page, flags=re.MULTILINE)
    by_path = {s.split("`")[1]: s for s in sections if s.startswith("`")}
    missing = []
    for path, command, ctx in hook.iter_commands():
        section = by_path.get(path)
        if section is None:
            missing.append(path)
            continue
        for param in command.get_params(ctx):
            if getattr(param, "hidden", False) or "--help" in param.opts:
                continue
            if not param.opts[0].startswith("-"):  # an argument: shown by its metavar
                record = param.get_help_record(ctx)
                shown = record[0] if record else param.make_metavar(ctx)
                if f"`{shown}`" not in section:
                    missing.append(f"{path} {shown}")
                continue
            names = [*param.opts, *param.secondary_opts]
            missing += [f"{path} {name}" for name in names if name not in section]
    assert not missing, f"not on the generated command page: {missing}"
    assert "{#fuelid-identify}" in page  # the anchors the other pages link to
    assert "`-20.0`" in page  # the defaults


def test_the_command_page_holds_the_hooks_marker() -> None:
    hook = load_hook()
    assert hook.MARKER in (REFERENCE / "cli.md").read_text(encoding="utf-8")


# --- (c) the nav and the links -------------------------------------------------------------------


def mkdocs_config() -> str:
    return (ROOT / "mkdocs.yml").read_text(encoding="utf-8")


def nav_pages() -> list[str]:
    """The pages the nav lists (``- Title: page.md`` or ``- page.md``), read without YAML."""
    nav = mkdocs_config().split("\nnav:", 1)[1]
    return re.findall(r"^\s*-\s+(?:[^\n]*?:\s+)?([\w./-]+\.md)\s*$", nav, flags=re.MULTILINE)


def excluded(page: Path) -> bool:
    """Whether ``exclude_docs`` of mkdocs.yml leaves a page out of the site."""
    block = re.search(r"^exclude_docs: \|\n((?:[ \t]+.*\n)+)", mkdocs_config(), re.MULTILINE)
    patterns = [] if block is None else [ln.strip() for ln in block.group(1).splitlines()]
    relative = page.relative_to(DOCS).as_posix()
    for pattern in patterns:
        if not pattern or pattern.startswith("#"):
            continue
        if pattern.endswith("/") and relative.startswith(pattern.lstrip("/")):
            return True
        if pattern.startswith("/") and relative == pattern[1:]:
            return True
    return False


def site_pages() -> list[Path]:
    return [p for p in sorted(DOCS.rglob("*.md")) if not excluded(p)]


def test_every_nav_page_exists_and_every_page_is_in_the_nav() -> None:
    listed = nav_pages()
    assert "reference/cli.md" in listed
    absent = [page for page in listed if not (DOCS / page).is_file()]
    assert not absent, f"in the nav of mkdocs.yml but not in docs/: {absent}"
    pages = [p.relative_to(DOCS).as_posix() for p in site_pages()]
    unlisted = [page for page in pages if page not in listed]
    assert not unlisted, f"pages not in the nav of mkdocs.yml (the strict build fails): {unlisted}"


_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def test_every_relative_link_in_the_docs_resolves() -> None:
    broken = []
    for page in site_pages():
        text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.DOTALL)
        for target in _LINK.findall(text):
            if re.match(r"^[a-z]+:", target) or target.startswith("#"):
                continue  # another site, or an anchor on the same page
            path = target.split("#", 1)[0]
            if not (page.parent / path).resolve().exists():
                broken.append(f"{page.relative_to(DOCS)}: {target}")
    assert not broken, f"links to files that do not exist: {broken}"
