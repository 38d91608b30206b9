"""``fuelid dashboard user add|remove|rotate|list`` end to end, through ``fuelid.cli.main``.

From the dashboard issue: a token is shown once and never stored; ``list`` shows no token; bad
input exits 2 with a one-line reason on stderr (the command-line contract).
"""

from __future__ import annotations

import hashlib
import json
import re
import stat
import sys
from pathlib import Path

import pytest

from fuelid.cli import main

TOKEN = re.compile(r"^[A-Za-z0-9_-]{43}$")


@pytest.fixture(autouse=True)
def in_a_fresh_folder(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """``fuelid dashboard user`` runs in a fresh folder, where the default users file lands."""
    monkeypatch.chdir(tmp_path)


def tokens_in(text: str) -> list[str]:
    return [line for line in text.splitlines() if TOKEN.match(line.strip())]


def test_add_prints_the_token_once_and_stores_only_its_sha256(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["dashboard", "user", "add", "ana", "--role", "engineer"]) == 0
    out = capsys.readouterr().out
    (token,) = tokens_in(out)
    assert out.count(token) == 1
    assert "cannot be shown again" in out
    users_file = tmp_path / "dashboard-users.json"  # the default, in the current folder
    text = users_file.read_text(encoding="utf-8")
    assert token not in text
    assert json.loads(text)["users"]["ana"]["sha256"] == hashlib.sha256(token.encode()).hexdigest()
    if sys.platform != "win32":
        assert stat.S_IMODE(users_file.stat().st_mode) == 0o600


def test_list_shows_names_and_roles_but_no_token(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    users = str(tmp_path / "u.json")
    assert main(["dashboard", "user", "add", "ana", "--role", "engineer", "--users", users]) == 0
    assert main(["dashboard", "user", "add", "ben", "--role", "viewer", "--users", users]) == 0
    issued = tokens_in(capsys.readouterr().out)
    assert len(issued) == 2

    assert main(["dashboard", "user", "list", "--users", users]) == 0
    table = capsys.readouterr().out
    assert re.search(r"^ana\s+engineer\s", table, re.MULTILINE)
    assert re.search(r"^ben\s+viewer\s", table, re.MULTILINE)
    assert tokens_in(table) == []
    assert all(token not in table for token in issued)

    assert main(["dashboard", "user", "list", "--users", users, "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert [(u["name"], u["role"], u["rotated"]) for u in listed["users"]] == [
        ("ana", "engineer", None),
        ("ben", "viewer", None),
    ]
    assert set(listed["users"][0]) == {"name", "role", "created", "rotated"}
    assert all(token not in json.dumps(listed) for token in issued)


def test_rotate_prints_a_new_token_and_the_old_one_stops_working(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from fuelid.dashboard import UsersFile

    assert main(["dashboard", "user", "add", "ana", "--role", "viewer"]) == 0
    (old,) = tokens_in(capsys.readouterr().out)
    assert main(["dashboard", "user", "rotate", "ana"]) == 0
    out = capsys.readouterr().out
    (new,) = tokens_in(out)
    assert new != old
    assert "cannot be shown again" in out
    users = UsersFile("dashboard-users.json")
    assert users.verify("ana", old) is None
    assert users.verify("ana", new) is not None


def test_remove_takes_the_user_out(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["dashboard", "user", "add", "ana", "--role", "viewer"]) == 0
    assert main(["dashboard", "user", "remove", "ana"]) == 0
    capsys.readouterr()
    assert main(["dashboard", "user", "list", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["users"] == []


def one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("error: ")
    assert "Traceback" not in captured.err
    return lines[0]


def test_a_bad_role_exits_2_with_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["dashboard", "user", "add", "ana", "--role", "admin"]) == 2
    assert "admin" in one_line_error(capsys)
    assert not Path("dashboard-users.json").exists()


def test_a_bad_name_exits_2_with_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["dashboard", "user", "add", "<b>", "--role", "viewer"]) == 2
    assert "not allowed" in one_line_error(capsys)


def test_removing_an_unknown_user_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["dashboard", "user", "add", "ana", "--role", "viewer"]) == 0
    capsys.readouterr()
    assert main(["dashboard", "user", "remove", "bob"]) == 2
    assert "no user 'bob'" in one_line_error(capsys)


def test_a_missing_users_file_exits_2_with_the_reason(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["dashboard", "user", "list", "--users", "absent.json"]) == 2
    assert "absent.json does not exist" in one_line_error(capsys)


def test_a_broken_users_file_exits_2_naming_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    broken = tmp_path / "broken.json"
    broken.write_text("{not json", encoding="utf-8")
    assert main(["dashboard", "user", "rotate", "ana", "--users", str(broken)]) == 2
    line = one_line_error(capsys)
    assert "broken.json" in line
    assert "not JSON" in line


def test_help_says_where_the_users_file_defaults_to(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["dashboard", "user", "add", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "dashboard-users.json in the current folder" in out
