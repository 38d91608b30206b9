"""The xdist groups of `make test` still group with the installed pytest and pytest-xdist.

The modules that drive a PLC at speed, and the dashboard's, carry
``pytest.mark.xdist_group(...)`` so that ``--dist loadgroup`` gives each group to one worker
(tests/conftest.py says why). pytest-xdist 3.8 under pytest 9.2 silently spreads a group over the
workers (pytest-dev/pytest-xdist#1386: xdist writes the group into ``item._nodeid``, which
pytest 9.2's structured node ids no longer read); pyproject.toml pins pytest below 9.2 until an
xdist release fixes it. An upgrade that breaks the grouping again fails here, not as a flaky
real-time test on a loaded machine.
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("xdist", reason="pytest-xdist (the dev extra) is not installed")

pytest_plugins = ["pytester"]

GROUPED = """
import pytest

pytestmark = pytest.mark.xdist_group("together")


@pytest.mark.parametrize("i", range(4))
def test_where(i, worker_id, request):
    with open({record!r}, "a") as out:
        out.write(f"{{request.node.nodeid}} {{worker_id}}\\n")
"""


def test_an_xdist_group_runs_on_one_worker(pytester: pytest.Pytester, tmp_path: Path) -> None:
    record = tmp_path / "workers.txt"
    module = GROUPED.format(record=str(record))
    pytester.makepyfile(test_first=module, test_second=module)
    result = pytester.runpytest_subprocess(
        "-n", "2", "--dist", "loadgroup", "-p", "no:cacheprovider"
    )
    result.assert_outcomes(passed=8)
    ran = dict(line.rsplit(" ", 1) for line in record.read_text().splitlines())
    assert len(ran) == 8, ran
    assert len(set(ran.values())) == 1, (
        "--dist loadgroup spread one xdist_group over the workers "
        f"(pytest-dev/pytest-xdist#1386; see the pytest pin in pyproject.toml): {ran}"
    )
