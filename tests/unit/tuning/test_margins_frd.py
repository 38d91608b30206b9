"""Cross-check of fuelid's exact-delay margins against python-control's on frequency-response data.

fuelid evaluates the loop with the dead time as the exact factor e^(−jωθ) (continuous) or through
the modified z-transform (sampled PI + ZOH) and refines crossings with Brent's method. Here the
same loop is built independently with python-control (its transfer functions, ``c2d`` with a
zero-order hold, the PLC's forward-Euler PI as a discrete transfer function, the delay as the
exact factor e^(−jωθ) or z^(−d)), tabulated as an FRD, and ``control.stability_margins`` reads
the margins from it. Sampled cases use whole-sample delays, which ``c2d`` represents exactly
(fractional delays are checked against the modified z-transform by hand in test_tuning.py).
"""

from __future__ import annotations

import control
import numpy as np
import pytest

from fuelid.model import ProcessModel
from fuelid.tuning import PISettings, robustness

CASES = [
    # (model, Kc, Ti, control period)
    (ProcessModel(K=1.0, T=2.0, delay=1.0), 1.0, 2.0, 0.0),  # SIMC worked example, continuous
    (ProcessModel(K=1.0, T=2.0, delay=1.0), 0.41, 1.84, 0.0),  # AMIGO worked example
    (
        ProcessModel(K=13.55, T=1.26, T_f=0.3, delay=0.37),
        0.0613,
        1.41,
        0.0,
    ),  # fuel loop, fractional
    (ProcessModel(K=13.55, T=1.26, T_f=0.3, delay=1.0), 0.05, 1.41, 1.0),  # fuel loop, h = 1 s
    (ProcessModel(K=2.0, T=5.0, T2=1.5, delay=1.5), 0.6, 5.0, 0.5),  # second order, 3 samples
]


def _loop_by_python_control(
    model: ProcessModel, Kc: float, Ti: float, h: float, omega: np.ndarray
) -> np.ndarray:
    """L(jω) or L(e^(jωh)) from python-control's own objects, delay exact."""
    den = [1.0]
    for tc in model.time_constants:
        den = list(np.polymul(den, [tc, 1.0]))
    plant = control.tf([model.K], den)
    if h == 0.0:
        pi = control.tf([Kc * Ti, Kc], [Ti, 0.0])
        delay = np.exp(-1j * omega * model.delay)
        return np.asarray((plant * pi)(1j * omega) * delay, dtype=complex)
    shift = round(model.delay / h)
    assert abs(shift * h - model.delay) < 1e-12, "sampled cases use whole-sample delays"
    sampled = control.c2d(plant, h, method="zoh")
    # u(k) = Kc·e(k) + (Kc·h/Ti)·Σ_{j<k} e(j): C(z) = Kc·(1 + (h/Ti)·z⁻¹/(1 − z⁻¹))
    pi = control.tf([Kc, Kc * (h / Ti - 1.0)], [1.0, -1.0], h)
    z = np.exp(1j * omega * h)
    return np.asarray((sampled * pi)(z) * z ** (-shift), dtype=complex)


def _frd_margins(
    model: ProcessModel, pi: PISettings, omega: np.ndarray
) -> tuple[float, float, float]:
    """(gain margin, phase margin [deg], Ms) by python-control on the loop's FRD."""
    response = _loop_by_python_control(model, pi.Kc, pi.Ti, pi.control_period, omega)
    frd = control.frd(response, omega)
    gm, pm, _, _, _, _ = control.stability_margins(frd)
    ms = float(np.max(np.abs(1.0 / (1.0 + response))))
    return float(gm), float(pm), ms


@pytest.mark.parametrize(("model", "Kc", "Ti", "h"), CASES)
def test_margins_agree_with_python_control_on_an_frd(
    model: ProcessModel, Kc: float, Ti: float, h: float
) -> None:
    pi = PISettings(rule="given", Kc=Kc, Ti=Ti, control_period=h)
    top = np.pi / h * 0.9999 if h > 0.0 else 200.0
    omega = np.geomspace(1e-3, top, 5_001)
    gm_ref, pm_ref, ms_ref = _frd_margins(model, pi, omega)
    ours = robustness(model, pi)
    assert ours.stable
    assert ours.gain_margin == pytest.approx(gm_ref, rel=1e-3)
    assert ours.phase_margin_deg == pytest.approx(pm_ref, abs=0.05)
    # the dense grid can only under-read a peak; fuelid refines it
    assert ms_ref <= ours.Ms * (1.0 + 1e-9)
    assert ours.Ms == pytest.approx(ms_ref, rel=1e-4)
