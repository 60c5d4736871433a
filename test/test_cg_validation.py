"""Model validation of the static CG fit (statics.CgValidation): a verdict and named checks.

* the clean reference pair passes every check;
* a body that tilts more under the dummy mass than the frame on its cables allows -- here the
  dummy recording's inclinometer reads 2 % more tilt change than the frame's (an inclinometer
  on a vehicle that rolls on its unlocked suspension), hand-made on the shipped recording
  because the simulator's ``compliant_body`` holds the sprung body at its nominal pose in every
  static state (its spring pre-load is set at each recording's own equilibrium) -- fails
  ``tilt_change``, warns, and the CLI's JSON carries it;
* an inclinometer zero offset fails ``inclinometer_level`` (geometry exact) and is absorbed by
  ``--fit-inclinometer-offset``;
* the limit of any static test: a sprung mass that slides downhill equally in every direction
  (isotropic suspension) is the same, to first order, as a rigid body whose CG is higher by
  h = (m_s / m) g / ω² -- the ship's "free-surface" rise of G -- so the fit reports c + h·up
  and no check can tell (docs/cg.md: lock the suspension).
"""
import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import REPO, recording

from rig_identification.cli.main import identify_main
from rig_identification.io.recording import SensorData, TimeSeries, read_recording
from rig_identification.io.recording_writer import write_recording
from rig_identification.io.rig import DummyMass
from rig_identification.model.experiment import load_experiment
from rig_identification.model.simulator import simulate
from rig_identification.statics import VALIDATION_SIGMA, CgOptions, StaticState, estimate_cg, static_equilibrium

REFERENCE_NOISE = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5, "inclinometer": 2e-4}
RATES = {"imu": 200.0, "load_cells": 200.0, "exciter": 200.0, "inclinometer": 50.0}


@pytest.fixture(scope="module")
def pair():
    b = read_recording(recording("visible_case16_static/static_baseline"))
    d = read_recording(recording("visible_case16_static/static_dummy"))
    return b, d


def with_inclinometer(sensors: SensorData, add) -> SensorData:
    inc = sensors.inclinometer
    return SensorData(sensors.imu, sensors.load_cells, sensors.exciter, TimeSeries(inc.t, inc.data + add))


def test_clean_pair_passes_every_check(pair):
    b, d = pair
    res = estimate_cg(b.rig, StaticState.from_recording(b, label="baseline"),
                      StaticState.from_recording(d, label="dummy"))
    v = res.validation
    assert v.verdict == "ok" and not v.failed
    names = [c.name for c in v.checks]
    assert names == ["fit_chi2", "tilt_change", "inclinometer_level", "mass"]
    tilt = v.checks[1]
    assert tilt.passed and tilt.statistic < VALIDATION_SIGMA and tilt.threshold == VALIDATION_SIGMA


def test_body_tilting_more_than_the_frame_is_flagged(pair, tmp_path, capsys):
    b, d = pair
    sb = StaticState.from_recording(b, label="baseline")
    clean = StaticState.from_recording(d, label="dummy")
    extra = 0.02 * (clean.elevations - sb.elevations)             # 2 % more tilt change: ~90 µrad
    sd = StaticState.from_window(with_inclinometer(d.sensors, extra), label="dummy")
    res = estimate_cg(b.rig, sb, sd)
    assert res.validation.verdict == "model_error" and "tilt_change" in res.validation.failed
    tilt = next(c for c in res.validation.checks if c.name == "tilt_change")
    assert tilt.statistic > VALIDATION_SIGMA
    warn = [w for w in res.warnings if w.startswith("model validation: check tilt_change failed")]
    assert warn and "compliant body" in warn[0] and "lock the suspension" in warn[0]
    # the apparent CG rose: the fit read the extra tilt as a higher CG
    truth = np.array(b.truth["center_of_gravity"], float)
    assert res.center_of_gravity[2] - truth[2] > 5 * res.center_of_gravity_std_noise[2]
    # the command line: a warning line naming the check, and the JSON's validation
    rec = write_recording(tmp_path / "dummy", d.rig, with_inclinometer(d.sensors, extra), d.truth)
    assert identify_main(["cg", str(b.path), str(rec), "--json"]) == 0
    j = json.loads(capsys.readouterr().out)
    assert j["validation"]["verdict"] == "model_error" and "tilt_change" in j["validation"]["failed"]
    check = next(c for c in j["validation"]["checks"] if c["name"] == "tilt_change")
    assert check["passed"] is False and check["statistic"] > check["threshold"] == VALIDATION_SIGMA
    assert identify_main(["cg", str(b.path), str(rec)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("validation: MODEL ERROR") and "warning: model validation: check tilt_change failed" in out


def test_inclinometer_zero_offset_fails_the_level_check(pair):
    b, d = pair
    off = np.array([4e-4, 0.0])                                   # 0.4 mrad on the inclinometer's x axis
    sb = StaticState.from_window(with_inclinometer(b.sensors, off), label="baseline")
    sd = StaticState.from_window(with_inclinometer(d.sensors, off), label="dummy")
    exact = CgOptions.exact_geometry()
    res = estimate_cg(b.rig, sb, sd, exact)
    assert "inclinometer_level" in res.validation.failed and "tilt_change" not in res.validation.failed
    assert any("inclinometer.rpy" in w for w in res.warnings)
    fitted = estimate_cg(b.rig, sb, sd, replace(exact, fit_inclinometer_offset=True))
    assert fitted.validation.verdict == "ok"
    level = next(c for c in fitted.validation.checks if c.name == "inclinometer_level")
    assert level.passed is None                                   # absorbed by the fitted offsets
    np.testing.assert_allclose(fitted.inclinometer_offset, off, atol=3e-5)


def test_isotropic_compliant_body_is_a_higher_rigid_cg():
    """The sprung mass (share s of m) slides downhill by g δĝ / ω² when the frame tilts; with
    h = s g / ω² = 19 mm the fit must report the CG 19 mm higher along the baseline's vertical,
    and pass its checks: a static test cannot see it."""
    exp = load_experiment(REPO / "config" / "cases" / "case16.yaml")
    dummy = DummyMass(50.0, np.array([0.5, 0.5, 0.3]))
    exp = replace(exp, rig=replace(exp.rig, dummy_mass=dummy),
                  sensors=replace(exp.sensors, noise=dict(REFERENCE_NOISE), rates=dict(RATES)))
    c, m, h = exp.cg, exp.mass, 0.019
    R0, _, _ = static_equilibrium(exp.rig, m, c, (), 2e-7)
    R1, _, _ = static_equilibrium(exp.rig, m, c, (dummy,), 2e-7)
    down0, down1 = R0.T @ [0.0, 0.0, -1.0], R1.T @ [0.0, 0.0, -1.0]   # gravity's direction, body axes
    shifted = c + h * (down1 - down0)                                  # the body's CG in the dummy state
    states = []
    for kind, cg in (("baseline", c), ("dummy", shifted)):
        e = exp.with_overrides(static=kind)
        e = replace(e, rig=replace(e.rig, center_of_gravity=np.asarray(cg)))
        res = simulate(e)
        states.append(StaticState.from_window(res.sensors, label=kind))
    fit = estimate_cg(res.rig, *states, CgOptions.exact_geometry())
    expected = c - h * down0                                           # c + h · up
    assert np.all(np.abs(fit.center_of_gravity - expected) < 3 * fit.center_of_gravity_std + 2e-4), \
        (fit.center_of_gravity - expected) * 1e3
    assert fit.center_of_gravity[2] - c[2] > 0.9 * h                   # 19 mm too high ...
    assert fit.validation.verdict == "ok"                              # ... and nothing to see
