"""MkDocs hook: the command reference, rendered from the ``fuelid`` command tree at build time.

The option help texts in ``src/fuelid/cli`` are the one source of truth: this hook walks the
typer app's command tree and writes each command's usage, help text, arguments and options (with
the defaults ``--help`` shows) into ``docs/reference/cli.md`` where that page holds the marker
``<!-- fuelid-cli-reference -->``. Nothing generated is committed, so the page cannot go stale.

typer (0.29 and later) carries its own copy of click, so mkdocs-click, which walks click's classes,
does not see it; the tree is walked here by the attributes every click-like command has
(``commands``, ``params``, ``get_help_record``), the way ``fuelid.cli.main`` recognises its usage
errors. ``tests/unit/test_docs_reference.py`` imports :func:`render_cli_reference` to check that
every command and option reaches the page without building the site.
"""

from __future__ import annotations

import inspect
import re
from typing import Any

MARKER = "<!-- fuelid-cli-reference -->"
PAGE = "reference/cli.md"
#: ``<!-- fuelid-module-doc: fuelid.store._schema -->`` on any page is replaced by that module's
#: docstring (Markdown), so a fact documented in the code (the store's schema) lives there once
MODULE_DOC = re.compile(r"<!-- fuelid-module-doc: (?P<module>[\w.]+) -->")

_DEFAULT = re.compile(r"\s*\[(default: (?P<default>[^\]]*)|(?P<required>required))\]\s*$")


def root_command() -> Any:
    """The click-like command tree of ``fuelid`` (what ``fuelid --help`` walks)."""
    import typer

    from fuelid.cli import app

    return typer.main.get_command(app)


def _context(command: Any, name: str, parent: Any = None) -> Any:
    return command.context_class(command, info_name=name, parent=parent)


def iter_commands(command: Any | None = None) -> list[tuple[str, Any, Any]]:
    """Every visible command as ``(path, command, context)``, the root first, depth first."""
    root = root_command() if command is None else command
    found: list[tuple[str, Any, Any]] = []

    def walk(cmd: Any, path: str, ctx: Any) -> None:
        found.append((path, cmd, ctx))
        for name in cmd.list_commands(ctx) if hasattr(cmd, "commands") else []:
            sub = cmd.get_command(ctx, name)
            if sub is None or getattr(sub, "hidden", False):
                continue
            walk(sub, f"{path} {name}", _context(sub, name, ctx))

    walk(root, "fuelid", _context(root, "fuelid"))
    return found


def _escape(text: str) -> str:
    """Help text as Markdown table text: no cell breaks, no HTML, no accidental emphasis."""
    text = " ".join(text.split())
    for char, escaped in (("\\", "\\\\"), ("|", "\\|"), ("<", "&lt;"), ("*", "\\*")):
        text = text.replace(char, escaped)
    return text


def _code(text: str) -> str:
    # Python-Markdown's tables do not split a cell at a pipe inside a code span, and an escaped
    # pipe there would show its backslash: the text goes in as it is
    return f"`{text}`"


def _paragraphs(help_text: str) -> str:
    # click's ``\b`` marks a paragraph that must not be rewrapped; Markdown keeps lines anyway
    lines = [line for line in inspect.cleandoc(help_text).splitlines() if line.strip() != "\b"]
    return "\n".join(lines).replace("<", "&lt;")


def _anchor(path: str) -> str:
    return path.replace(" ", "-")


def param_rows(command: Any, ctx: Any) -> list[tuple[str, str, str]]:
    """``(names, help, default)`` of each visible argument and option, as ``--help`` shows it.

    ``--help`` itself is left out: every command has it.
    """
    rows: list[tuple[str, str, str]] = []
    for param in command.get_params(ctx):
        if getattr(param, "hidden", False) or "--help" in getattr(param, "opts", []):
            continue
        record = param.get_help_record(ctx)
        if record is None:  # an argument without a help text
            names, help_text = param.make_metavar(ctx).upper(), ""
        else:
            names, help_text = record
        default = ""
        match = _DEFAULT.search(help_text)
        if match:
            default = "required" if match.group("required") else match.group("default")
            help_text = help_text[: match.start()]
        rows.append((names, help_text, default))
    return rows


def render_command(path: str, command: Any, ctx: Any) -> str:
    """One command's section: heading, help text, usage and the table of its parameters."""
    depth = path.count(" ")
    heading = "#" * min(2 + max(depth - 1, 0), 4)
    out = [f"{heading} `{path}` {{#{_anchor(path)}}}", ""]
    if command.help:
        out += [_paragraphs(command.help), ""]
    usage = " ".join(command.collect_usage_pieces(ctx))
    out += ["```text", f"{ctx.command_path} {usage}".rstrip(), "```", ""]
    rows = param_rows(command, ctx)
    if rows:
        out += ["| argument or option | meaning | default |", "|---|---|---|"]
        for names, help_text, default in rows:
            shown = _code(default) if default and default != "required" else default
            out.append(f"| {_code(names)} | {_escape(help_text)} | {shown} |")
        out.append("")
    if hasattr(command, "commands"):
        subs = [
            (name, command.get_command(ctx, name))
            for name in command.list_commands(ctx)
            if not getattr(command.get_command(ctx, name), "hidden", False)
        ]
        out += ["| command | what it does |", "|---|---|"]
        for name, sub in subs:
            short = sub.get_short_help_str(limit=120)
            out.append(f"| [`{path} {name}`](#{_anchor(f'{path} {name}')}) | {_escape(short)} |")
        out.append("")
    return "\n".join(out)


def render_cli_reference(command: Any | None = None) -> str:
    """The whole command reference as Markdown (every command, argument, option, default)."""
    return "\n".join(render_command(path, cmd, ctx) for path, cmd, ctx in iter_commands(command))


def render_module_doc(module: str) -> str:
    """A module's docstring, cleaned of its indentation, as Markdown."""
    import importlib

    doc = importlib.import_module(module).__doc__
    if not doc:
        raise ValueError(f"{module} has no docstring to put in the docs")
    return inspect.cleandoc(doc)


#: a Sphinx cross-reference as the docstrings write it (``:class:`~fuelid.model.ProcessModel```),
#: after Markdown made its target a code span; mkdocstrings does not read Sphinx roles
_SPHINX_ROLE = re.compile(
    r":(?:py:)?(?:mod|class|func|meth|attr|data|exc|obj|const):<code>(?P<short>~?)(?P<name>[^<]+)</code>"
)


def plain_roles(html: str) -> str:
    """Sphinx roles in rendered docstrings as plain code: ``~a.b.C`` shows ``C``, as Sphinx does."""

    def code(match: re.Match[str]) -> str:
        name = match.group("name")
        return f"<code>{name.rsplit('.', 1)[-1] if match.group('short') else name}</code>"

    return _SPHINX_ROLE.sub(code, html)


def on_page_content(html: str, page: Any, **_: Any) -> str:
    """MkDocs event: docstrings without Sphinx role markup, wherever a page shows one.

    The API pages, the module docstrings a ``fuelid-module-doc`` marker puts on a reference
    page, and the benchmark pages' introductions (their scripts' docstrings).
    """
    return plain_roles(html)


def on_page_markdown(markdown: str, page: Any, **_: Any) -> str:
    """MkDocs event: put the generated reference where a page holds a marker."""
    markdown = MODULE_DOC.sub(lambda m: render_module_doc(m.group("module")), markdown)
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown:
        raise ValueError(f"{PAGE} lost its marker {MARKER}: the command reference has no place")
    return markdown.replace(MARKER, render_cli_reference())
