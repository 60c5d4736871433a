"""Joint identification over several recordings of the same body (issue 7).

Two short simulated recordings of thesis case 16 (realistic noise), the exciter at two
positions and frequencies: the joint fit recovers the true tensor and is more certain
than either recording alone; recordings of different bodies are refused with a clear
error naming the files (exit status 2 from the command line).
"""
import copy
import dataclasses
import inspect

import numpy as np
import pytest
from conftest import REPO, run_cli

from rig_identification.estimation.identification import identify_inertia, identify_inertia_joint
from rig_identification.estimation.inertia_result import compare_to_truth
from rig_identification.io.recording import Recording, RecordingError
from rig_identification.io.rig import RigError, dump_rig, read_yaml
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import experiment_from_dict
from rig_identification.model.parametrisation import physically_consistent
from rig_identification.model.simulator import simulate
from rig_identification.pipeline import offline as pipeline

DEFAULT = REPO / "config" / "rigs" / "default.yaml"
# exciter A: the thesis's (corner, below the CG), 1.05 Hz; B: the opposite corner, 0.95 Hz
SETTINGS = {"A": ([-0.8, -1.25, -0.46], 1.05, 5), "B": ([0.8, 1.25, -0.46], 0.95, 6)}
DURATION = 45.0


def _experiment(name: str):
    pos, freq, seed = SETTINGS[name]
    d = copy.deepcopy(read_yaml(DEFAULT, RigError, "experiment"))
    d["rig"]["exciter"]["position"] = pos
    d["excitation"]["rotating"]["frequency"] = freq
    d.update(name=name, duration=DURATION, seed=seed)
    return experiment_from_dict(d, f"{DEFAULT} ({name})")


@pytest.fixture(scope="module")
def recs(tmp_path_factory):
    out = {}
    for name in SETTINGS:
        sim = simulate(_experiment(name))
        out[name] = Recording(sim.rig, sim.sensors, sim.truth, tmp_path_factory.mktemp("joint") / name)
    return out


_PREPARED: dict = {}


@pytest.fixture
def cached_prepare(monkeypatch):
    """Run the tracker/preprocessor once per recording in this module (memoised, not faked)."""
    real, cache = pipeline.prepare_recording, _PREPARED

    sig = inspect.signature(real)

    def prep(rec, *a, **k):
        bound = sig.bind(rec, *a, **k)
        bound.apply_defaults()
        key = (id(rec), *list(bound.arguments.values())[1:])
        if key not in cache:
            cache[key] = real(rec, *a, **k)
        return cache[key]
    monkeypatch.setattr(pipeline, "prepare_recording", prep)


def test_joint_fit_recovers_truth_and_beats_each_recording(recs, cached_prepare):
    truth = recs["A"].truth
    single = {n: pipeline.identify_recording(r) for n, r in recs.items()}
    joint = pipeline.identify_recordings([recs["A"], recs["B"]])
    cmp = compare_to_truth(joint, truth)
    for k in KEYS:
        assert abs(cmp[k]["error_percent"]) < 0.5, (k, cmp[k])
        assert abs(cmp[k]["error_sigma"]) < 3.0, (k, cmp[k])
    assert physically_consistent(joint.inertia)
    a, b = single["A"], single["B"]
    # information adds: the white-noise (Cramér–Rao) std of every entry is below either recording's
    assert np.all(joint.crb_std < np.minimum(a.crb_std, b.crb_std)), (joint.crb_std, a.crb_std, b.crb_std)
    # the reported std (each recording's noise propagated through the chain, combined):
    # the uncertainty volume (geometric mean of the σ of the covariance's eigen-directions) is below
    # either recording's, and no entry is less certain than in the less informative recording
    vol = {n: np.linalg.det(r.covariance) ** (1 / 12) for n, r in (("A", a), ("B", b), ("joint", joint))}
    assert vol["joint"] < min(vol["A"], vol["B"]), vol
    assert np.all(joint.inertia_std < np.maximum(a.inertia_std, b.inertia_std)), \
        (joint.inertia_std, a.inertia_std, b.inertia_std)
    # the joint result knows its recordings: one fit series per recording, each fitted well
    assert [s.label for s in joint.series] == ["A", "B"]
    d = joint.to_dict()
    assert [r["label"] for r in d["recordings"]] == ["A", "B"]
    assert joint.n_samples == sum(len(s.t) for s in joint.series) == a.n_samples + b.n_samples
    for s in joint.series:
        r2 = 1 - np.sum(s.residual ** 2, 0) / np.sum(s.measured ** 2, 0)
        assert np.all(r2 > 0.99), (s.label, r2)


def test_single_segment_joint_is_identify_inertia(recs, cached_prepare):
    p = pipeline.prepare_recording(recs["B"])
    one = identify_inertia(p.rec.rig, p.t, p.gyro_body, p.torque)
    joint = identify_inertia_joint([p.rec.rig], [(p.t, p.gyro_body, p.torque)])
    np.testing.assert_array_equal(one.inertia, joint.inertia)
    np.testing.assert_array_equal(one.covariance, joint.covariance)
    np.testing.assert_array_equal(one.crb_std, joint.crb_std)
    np.testing.assert_array_equal(one.series[0].predicted, joint.series[0].predicted)
    # the fit's output series: predicted = measured − residual, and it carries the fit
    s = one.series[0]
    np.testing.assert_allclose(np.sqrt(np.mean(s.residual ** 2, 0)), one.residual_rms)
    cmp = compare_to_truth(one, recs["B"].truth)
    assert all(abs(cmp[k]["error_percent"]) < 1.0 for k in KEYS), cmp


@pytest.mark.parametrize("change", ["mass", "cg"])
def test_different_bodies_refused(recs, change):
    a, b = recs["A"], recs["B"]
    rig = b.rig
    if change == "mass":
        rig = dataclasses.replace(rig, mass=rig.mass * 1.01)
    else:
        rig = dataclasses.replace(rig, center_of_gravity=rig.center_of_gravity + np.array([0.0, 0.0, 0.005]))
    other = dataclasses.replace(b, rig=rig)
    with pytest.raises(RecordingError) as e:
        pipeline.identify_recordings([a, other])
    msg = str(e.value)
    assert str(a.path / "rig.yaml") in msg and str(b.path / "rig.yaml") in msg
    assert ("body.mass" if change == "mass" else "body.center_of_gravity") in msg
    # within the tolerance (a re-weighing, a CG re-measured to a millimetre) it is the same body
    close = dataclasses.replace(b.rig, mass=b.rig.mass * (1 + 0.2 * pipeline.MASS_RTOL),
                                center_of_gravity=b.rig.center_of_gravity + 0.4 * pipeline.CG_TOL)
    pipeline.check_same_body([a, dataclasses.replace(b, rig=close)])


def test_cli_different_bodies_exit_2(recs, tmp_path):
    # the bodies are compared from rig.yaml before any bag is read
    for name, mass in (("light", None), ("heavy", 1900.0)):
        rig = recs["A"].rig if mass is None else dataclasses.replace(recs["A"].rig, mass=mass)
        (tmp_path / name).mkdir()
        (tmp_path / name / "rig.yaml").write_text(dump_rig(rig))
    code, _, err = run_cli("inertia", tmp_path / "light", tmp_path / "heavy")
    assert code == 2, err
    err = err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert str(tmp_path / "light" / "rig.yaml") in err and str(tmp_path / "heavy" / "rig.yaml") in err
    assert "body.mass" in err and "1810" in err and "1900" in err
