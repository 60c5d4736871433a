"""One body over several recordings: the rig model fitted to both at once.

Two short simulated recordings of thesis case 16 (realistic noise), the exciter at two
positions and frequencies: the joint fit recovers the true tensor and is more certain
than either recording alone; recordings of different bodies are refused with a clear
error naming the files (exit status 2 from the command line).
"""
import copy
import dataclasses
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import REPO, background, gather, run_cli

from rig_identification.cli.joint import print_joint
from rig_identification.io.recording import Recording, RecordingError
from rig_identification.io.rig import RigError, dump_rig, read_yaml
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import experiment_from_dict
from rig_identification.model.parametrisation import entry_scales, physically_consistent, to_tensor
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.joint import CG_TOL, MASS_RTOL, check_same_body, fit_recordings

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


def _joint_fit():
    """Job: runs A and B simulated and fitted at once (``rig-identify inertia A B``'s core); the
    truth and the :class:`~rig_identification.pipeline.joint.JointResult`."""
    recs = []
    for name in SETTINGS:
        sim = simulate(_experiment(name))
        recs.append(Recording(sim.rig, sim.sensors, sim.truth, Path(name)))
    return recs[0].truth, fit_recordings(recs)


background("joint", __file__, _joint_fit, {"ab": ()}, first=True)


@pytest.fixture(scope="module")
def joint():
    return gather("joint", "ab")["ab"][1]


@pytest.fixture(scope="module")
def truth():
    return gather("joint", "ab")["ab"][0]


@pytest.fixture(scope="module")
def recs(tmp_path_factory):
    """The two runs' rig.yaml (no recording: the bodies are compared before any is read)."""
    return {name: SimpleNamespace(rig=_experiment(name).rig, path=tmp_path_factory.mktemp("joint") / name)
            for name in SETTINGS}


def test_joint_fit_recovers_truth_and_beats_each_recording(truth, joint):
    """One body over two runs: ok, every entry within 0.5 % and 3 σ of the truth; the information
    adds (σ and the Cramér–Rao bound below either run's alone on every entry); σ near the joint
    bound; each run's own channels at their noise; the body the same in each run's view."""
    assert joint.verdict == "ok", joint.summary
    mass = truth["mass"]
    truth = np.array([truth["inertia_about_cg"][k] for k in KEYS])
    f = joint.first.fit
    err = f.inertia - truth
    assert np.all(np.abs(err) / entry_scales(truth) < 0.005), err
    assert np.all(np.abs(err) / f.inertia_std < 3.0), err / f.inertia_std
    assert physically_consistent(to_tensor(f.inertia))
    for a in joint.alone:
        assert a.verdict == "ok", a.summary
        assert np.all(f.inertia_std < a.fit.inertia_std), (f.inertia_std, a.fit.inertia_std)
        assert np.all(f.crb < a.fit.crb), (f.crb, a.fit.crb)
    assert np.all(f.inertia_std < 1.5 * f.crb), f.inertia_std / f.crb
    for r in joint.results:
        np.testing.assert_array_equal(r.fit.inertia, f.inertia)
        np.testing.assert_array_equal(r.fit.inertia_std, f.inertia_std)
        assert r.fit.residual_level.max() < 1.5, dict(zip(r.fit.channels, r.fit.residual_level))
        # each run keeps its own states: the exciter's channels fitted to its own force
        assert r.fit.layout.n_force > 0
    assert abs(f.body.mass - mass) < 3 * f.body.std[9]


def test_joint_json_and_text(joint, capsys):
    """The JSON says one body over both recordings and what each determines alone; the text
    names both recordings and their verdicts before the tensor table."""
    d = joint.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["schema"] == "rig_identification.joint_rig_model_result" and d["verdict"] == "ok"
    assert [r["recording"] for r in d["recordings"]] == [str(joint.results[0].path), str(joint.results[1].path)]
    assert all(r["alone"]["verdict"] == "ok" and set(r["residual_level"]) for r in d["recordings"])
    assert "cables" not in d and "inertia_about_cg" in d and "truth_comparison" in d
    print_joint(joint)
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("verdict: ok") and out[1] == "recordings (one body, fitted at once): 2"
    assert str(joint.results[1].path) in out[3] and "alone ok" in out[3]


@pytest.mark.parametrize("change", ["mass", "cg"])
def test_different_bodies_refused(recs, change):
    a, b = recs["A"], recs["B"]
    rig = b.rig
    if change == "mass":
        rig = dataclasses.replace(rig, mass=rig.mass * 1.01)
    else:
        rig = dataclasses.replace(rig, center_of_gravity=rig.center_of_gravity + np.array([0.0, 0.0, 0.005]))
    other = SimpleNamespace(rig=rig, path=b.path)
    with pytest.raises(RecordingError) as e:
        fit_recordings([a, other])
    msg = str(e.value)
    assert str(a.path / "rig.yaml") in msg and str(b.path / "rig.yaml") in msg
    assert ("body.mass" if change == "mass" else "body.center_of_gravity") in msg
    # within the tolerance (a re-weighing, a CG re-measured to a millimetre) it is the same body
    close = dataclasses.replace(b.rig, mass=b.rig.mass * (1 + 0.2 * MASS_RTOL),
                                center_of_gravity=b.rig.center_of_gravity + 0.4 * CG_TOL)
    check_same_body([a, SimpleNamespace(rig=close, path=b.path)])


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
