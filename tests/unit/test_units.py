"""Unit constants: their values by definition, the conversion pairs, and their single home.

Every expected value is written from the unit's definition (1 L = 1e-3 m³, 1 min = 60 s, …),
never read back from :mod:`fuelid.units`.
"""

from __future__ import annotations

import ast
import itertools
import math
from pathlib import Path

import pytest

import fuelid
from fuelid import units
from fuelid.units import (
    LPM_PER_M3S,
    M3_PER_CM3,
    M_PER_MM,
    PA_PER_MPA,
    PA_S_PER_MPA_S,
    RAD_S_PER_RPM,
    T0,
    TWO_PI,
    W_PER_KW,
    celsius_to_kelvin,
    kelvin_to_celsius,
)


def test_constants_from_their_definitions() -> None:
    assert LPM_PER_M3S == 1000.0 * 60.0  # 1 m³ = 1000 L, 1 min = 60 s
    assert PA_PER_MPA == 1.0e6
    assert M_PER_MM == 1.0e-3
    assert pytest.approx((1.0e-2) ** 3, rel=1e-15) == M3_PER_CM3  # 1 cm = 1e-2 m
    assert PA_S_PER_MPA_S == 1.0e-3
    assert W_PER_KW == 1.0e3
    assert 2.0 * math.pi == TWO_PI
    assert pytest.approx(2.0 * math.pi / 60.0, rel=1e-15) == RAD_S_PER_RPM
    assert T0 == 273.15


@pytest.mark.parametrize(
    ("factor", "in_b", "in_a"),
    [
        (LPM_PER_M3S, 1.0e-3, 60.0),  # 1 L/s is 60 L/min
        (PA_PER_MPA, 1.2, 1.2e6),
        (M_PER_MM, 32.0, 0.032),
        (M3_PER_CM3, 50.0, 50.0e-6),  # a 50 cm³/rev pump
        (PA_S_PER_MPA_S, 1.02, 1.02e-3),  # kerosene at 20 °C, about 1 cP
        (W_PER_KW, 7.5, 7500.0),
        (RAD_S_PER_RPM, 1500.0, 50.0 * math.tau / 2.0),  # 2 pole pairs on 50 Hz
    ],
)
def test_conversion_pair_round_trip(factor: float, in_b: float, in_a: float) -> None:
    # A_PER_B: a value in B times the factor is the value in A, and back by division
    assert in_b * factor == pytest.approx(in_a, rel=1e-15)
    assert in_a / factor == pytest.approx(in_b, rel=1e-15)


@pytest.mark.parametrize("t_degC", [-40.0, -20.0, 0.0, 20.0, 50.0])
def test_kelvin_round_trip(t_degC: float) -> None:
    assert celsius_to_kelvin(t_degC) == pytest.approx(t_degC + 273.15, abs=1e-12)
    assert kelvin_to_celsius(celsius_to_kelvin(t_degC)) == pytest.approx(t_degC, abs=1e-12)


def test_every_constant_is_documented() -> None:
    tree = ast.parse(Path(units.__file__).read_text(encoding="utf-8"))
    body = tree.body
    documented = {
        node.target.id
        for node, after in itertools.pairwise(body)
        if isinstance(node, ast.AnnAssign)
        and isinstance(node.target, ast.Name)
        and isinstance(after, ast.Expr)
        and isinstance(after.value, ast.Constant)
        and isinstance(after.value.value, str)
    }
    constants = {name for name in vars(units) if name.isupper()}
    assert constants == documented


def test_every_conversion_has_a_doctest() -> None:
    # the module docstring's examples (run by --doctest-modules) convert there and back with each
    examples = [line for line in (units.__doc__ or "").splitlines() if line.startswith(">>> ")]
    constants = {name for name in vars(units) if name.isupper()} - {"T0"}
    for name in sorted(constants):
        assert any(line.count(name) >= 2 for line in examples), name
    assert any("celsius_to_kelvin" in line and "kelvin_to_celsius" in line for line in examples)


# --------------------------------------------------------------------------------------------
# the plant and the simulation convert with these constants only

SOURCE = Path(fuelid.__file__).parent
CONVERTING_MODULES = [
    *(f"plant/_{name}.py" for name in ("vfd", "motor", "shaft", "pump", "pipeline", "nozzle")),
    *(f"plant/_{name}.py" for name in ("flowmeter", "system", "config", "section")),
    "plant/simulate.py",
    "tuning/closedloop.py",
]
#: numbers that are unit factors (mm, MPa, cm³, mPa·s, kW, rpm, L/min, °C) wherever they appear
UNIT_FACTORS = {1e-3, 1e3, 1e-6, 1e6, 60.0, 60_000.0, 273.15}


def _code_literals(tree: ast.Module) -> list[tuple[int, str]]:
    """Unit-factor literals and ``2·math.pi`` products in function bodies (docstrings aside)."""
    found: list[tuple[int, str]] = []
    for function in ast.walk(tree):
        if not isinstance(function, ast.FunctionDef):
            continue
        body = function.body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]  # the docstring
        for statement in body:
            for node in ast.walk(statement):
                if (
                    isinstance(node, ast.Constant)
                    and isinstance(node.value, int | float)
                    and not isinstance(node.value, bool)
                    and float(node.value) in UNIT_FACTORS
                ):
                    found.append((node.lineno, repr(node.value)))
                if (
                    isinstance(node, ast.BinOp)
                    and isinstance(node.op, ast.Mult)
                    and "math.pi" in ast.unparse(node)
                    and any(
                        isinstance(side, ast.Constant) and side.value == 2
                        for side in (node.left, node.right)
                    )
                ):
                    found.append((node.lineno, ast.unparse(node)))
    return found


@pytest.mark.parametrize("module", CONVERTING_MODULES)
def test_no_unit_literals_outside_units(module: str) -> None:
    tree = ast.parse((SOURCE / module).read_text(encoding="utf-8"))
    assert _code_literals(tree) == [], f"{module}: use the constants of fuelid.units"


def test_the_literal_check_finds_literals() -> None:
    sample = ast.parse(
        "def f(d_mm, n, p_MPa):\n"
        '    """d in mm: d·1e-3 is m."""\n'
        "    return d_mm * 1e-3, 2.0 * math.pi * n / 60.0, p_MPa * 1e6\n"
    )
    found = {text for _, text in _code_literals(sample)}
    assert found == {"0.001", "2.0 * math.pi", "60.0", "1000000.0"}
