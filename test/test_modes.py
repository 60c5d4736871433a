"""Issue 7: natural modes from the geometry vs estimated from a recording."""
from dataclasses import replace

import numpy as np
import pytest
from conftest import REPO, recording

from rig_identification.io.recording import Recording, read_recording
from rig_identification.io.rig import inertia_tensor, rig_from_dict
from rig_identification.model.experiment import load_experiment
from rig_identification.model.modes import estimate_modes, match_modes, natural_modes
from rig_identification.model.simulator import simulate

G = 9.80665


def _parallel_rig(L=2.0, a=0.5, b=0.8):
    """Four vertical cables of length L on a rectangle 2a x 2b; body anchors at the CG height."""
    cables = [{"name": f"c{i}", "ceiling_anchor": [sx * a, sy * b, 0.0], "body_anchor": [sx * a, sy * b, 0.0],
               "length": L} for i, (sx, sy) in enumerate([(-1, -1), (1, -1), (-1, 1), (1, 1)])]
    return rig_from_dict({"gravity": G, "cables": cables, "body": {"mass": 100.0, "center_of_gravity": [0, 0, 0]},
                          "imu": {"position": [0, 0, 0], "rpy": [0, 0, 0]}})


def test_parallel_cables_swing_like_a_pendulum():
    L = 2.0
    rig = _parallel_rig(L)
    J = np.diag([20.0, 10.0, 25.0])
    f_pend = np.sqrt(G / L) / (2 * np.pi)
    ine = natural_modes(rig, 100.0, [0, 0, 0], J)
    # 4 vertical cables allow x, y (and a yaw whose frequency is sqrt(g/L * m r^2 / Jzz))
    assert len(ine) == 3
    swings = sorted(m.frequency for m in ine if m.description.startswith(("x-swing", "y-swing")))
    assert swings == pytest.approx([f_pend, f_pend], rel=1e-6)
    r2 = 0.5**2 + 0.8**2
    yaw = [m for m in ine if m.description.startswith("yaw")]
    assert yaw[0].frequency == pytest.approx(np.sqrt(G / L * 100.0 * r2 / 25.0) / (2 * np.pi), rel=1e-6)
    # very stiff springs -> the same swing frequencies (+ 3 stiff modes)
    spr = natural_modes(rig, 100.0, [0, 0, 0], J, stiffness=1e7)
    assert len(spr) == 6
    assert [m.frequency for m in spr[:2]] == pytest.approx([f_pend, f_pend], rel=1e-4)
    # bounce: sqrt(4k/m)
    bounce = [m for m in spr if m.description.startswith("bounce")][0]
    assert bounce.frequency == pytest.approx(np.sqrt(4e7 / 100.0) / (2 * np.pi), rel=1e-4)


def _check(geo, est, tol):
    pairs = match_modes(geo, est.modes)
    for m, e, d in pairs[:2]:
        assert e is not None, f"no estimate near {m.frequency:.3f} Hz ({[x.frequency for x in est.modes]})"
        assert abs(d) < 100 * tol, (m.frequency, e.frequency, d)
    return pairs


@pytest.fixture(scope="module")
def case16():
    return load_experiment(REPO / "config" / "cases" / "case16.yaml").with_overrides(duration=30.0, noise_free=True)


@pytest.mark.parametrize("amplitude, tol, n_modes", [(20.0, 0.005, 6)])
def test_case16_project_simulator(case16, amplitude, tol, n_modes):
    exp = replace(case16, excitation=replace(case16.excitation,
                                             rotating=replace(case16.excitation.rotating, amplitude=amplitude)))
    res = simulate(exp)
    est = estimate_modes(Recording(res.rig, res.sensors))
    assert est.exciter_frequency == pytest.approx(1.05, rel=1e-4)
    geo = natural_modes(exp.rig, exp.mass, exp.cg, exp.inertia, stiffness=5e6)
    pairs = _check(geo, est, tol)
    # small forcing: every mode (pendulum, yaw, 3 stiff) within 0.5 %
    for m, e, d in pairs[:n_modes]:
        if n_modes == 6:
            assert e is not None and abs(d) < 0.5, (m.frequency, d)
    ine = natural_modes(exp.rig, exp.mass, exp.cg, exp.inertia)
    assert len(ine) == 2
    _check(ine, est, 0.02)


def test_case16_reference_recording():
    rec = read_recording(recording("visible_case16_clean"))
    J = inertia_tensor(rec.truth["inertia_about_cg"])
    est = estimate_modes(rec)
    assert est.exciter_frequency == pytest.approx(1.05, rel=1e-4)
    f = sorted(e.frequency for e in est.modes)
    assert any(0.83 < x < 0.86 for x in f) and any(1.15 < x < 1.20 for x in f)
    for k in (5e6, None):
        geo = natural_modes(rec.rig, rec.truth["mass"], rec.truth["center_of_gravity"], J, stiffness=k)
        _check(geo, est, 0.02)
