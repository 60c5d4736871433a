"""What the rig model leaves out, named only where the recording tells it apart (issue 35).

Recordings of the package's simulator with one concealed effect, through the whole pipeline
(``fit_whole_recording``: the rig model, its diagnosis and the refit): the effect is named with
its value, the refit explains every channel and corrects the tensor.  The clean rigs' checks
(nothing named) are in test_rig_model.py.  The sweep over effects and random rigs is
``bench/bench_trust.py``.
"""
import contextlib
import io

import numpy as np
from conftest import background, gather

from rig_identification.cli.diagnose import print_rig_diagnosis_text
from rig_identification.design.scenarios import simulate_random
from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import entry_scales
from rig_identification.pipeline.rig_model import LEVEL_LIMIT, fit_whole_recording

DELAY = 0.008


def _diagnosed(effects: list, seconds: float):
    """Job: a random 4-cable 'wide' rig (seed 7001) with ``effects`` concealed, fitted and diagnosed;
    the truth, the JSON and ``rig-identify diagnose``'s text output."""
    _, sim = simulate_random(7001, 4, "wide", effects, seconds)
    res = fit_whole_recording(Recording(sim.rig, sim.sensors, sim.truth, None))
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        print_rig_diagnosis_text(res)
    return sim.truth, res.to_dict(), text.getvalue()


background("rig_diagnosis", __file__, _diagnosed, {
    "delay": ([{"name": "sensor_delay", "stream": "load_cells", "delay": DELAY}], 30.0),
}, first=True)


def test_a_load_cell_delay_is_named_fitted_and_the_tensor_corrected():
    """An 8 ms delay of the load cells: the rigid-body rig model does not find the motion (its
    tensions 20–30× their noise); the diagnosis names load_cell_delay, told apart from every other
    extension, and nothing else; the refit gives the delay within 3 σ and 0.2 ms, every channel
    but the exciter's within its noise level, and every tensor entry within 1 % and 3 σ."""
    truth, d, _ = gather("rig_diagnosis", "delay")["delay"]
    dg = d["diagnosis"]
    assert dg["named"] == ["load_cell_delay"] and dg["extensions"] == ["load_cell_delay"], dg["steps"]
    before = dg["residual_level_before"]
    assert min(v for c, v in before.items() if c.startswith("tension")) > 10, before
    ext = d["extensions"]["load_cell_delay"]
    assert abs(ext["values"][0] - DELAY) < max(3 * ext["std"][0], 2e-4), ext
    after = dg["residual_level_after"]
    assert all(v < LEVEL_LIMIT for c, v in after.items() if not c.startswith("exciter")), after
    tru = np.array([truth["inertia_about_cg"][k] for k in KEYS])
    est = np.array([d["inertia_about_cg"][k] for k in KEYS])
    sd = np.array([d["inertia_std"][k] for k in KEYS])
    assert np.all(np.abs(est - tru) < 0.01 * entry_scales(tru)), (est - tru) / entry_scales(tru)
    assert np.all(np.abs(est - tru) < 3 * sd), (est - tru) / sd


def test_diagnose_says_the_rigid_fit_what_was_named_and_the_fit_with_it():
    """``rig-identify diagnose``'s output on the delayed rig: the rigid-body rig model's verdict
    (not ok: the tensions far beyond their noise) in the text and the JSON's ``rigid_body_fit``,
    the extension named with its fitted value, each channel's residual before → after, and the
    model with the delay's verdict and tensor."""
    truth, d, text = gather("rig_diagnosis", "delay")["delay"]
    rb = d["rigid_body_fit"]
    assert rb["verdict"] in ("failed", "model_error") and d["verdict"] != rb["verdict"], (rb["verdict"], d["verdict"])
    assert min(v for c, v in rb["residual_level"].items() if c.startswith("tension")) > 10
    lines = text.splitlines()
    assert lines[2] == f"  verdict: {rb['summary']}", lines[:3]
    named = next(x for x in lines if x.startswith("  load_cell_delay: χ² falls"))
    assert named.endswith("cross-validated; named"), named
    fitted = lines[lines.index(named) + 1]
    ext = d["extensions"]["load_cell_delay"]
    assert fitted == f"    fitted: {ext['values'][0]:.4g} ± {ext['std'][0]:.2g} s", fitted
    assert any(x.startswith("  residual over the noise before → after: tension:c0 ") for x in lines)
    assert f"the model with load_cell_delay: verdict {d['verdict']}" in text
    iyy = next(x for x in lines if x.strip().startswith("Iyy"))
    assert f"{d['inertia_about_cg']['iyy']:.2f}" in iyy and f"{truth['inertia_about_cg']['iyy']:.2f}" in iyy, iyy


def test_a_fit_that_did_not_find_the_motion_names_nothing(capsys):
    """Where the last fit leaves a channel beyond 10× its noise its estimate is no minimum: the
    diagnosis says so, names nothing and gives no advice (a test at it is no evidence), and does
    not say the model explains the recording; at 1.2× it would."""
    from types import SimpleNamespace

    from rig_identification.cli.rig_model import print_diagnosis
    from rig_identification.diagnosis.rig_diagnosis import RigDiagnosis
    lost = SimpleNamespace(residual_level=np.array([0.98, 318.3, 11.0]), channels=("gyro_x", "tension:c0", "gyro_y"))
    dg = RigDiagnosis((), None, (), lost, None)
    assert not dg.found_motion and dg.named == () and dg.advice == [] and dg.to_dict()["found_motion"] is False
    print_diagnosis(dg)
    out = capsys.readouterr().out
    assert "did not find the motion" in out and "nothing is named" in out and "explains" not in out, out
    fits = SimpleNamespace(residual_level=np.array([0.98, 1.2, 1.0]), channels=lost.channels)
    assert RigDiagnosis((), None, (), fits, None).found_motion
    print_diagnosis(RigDiagnosis((), None, (), fits, None))
    assert "the model explains the recording" in capsys.readouterr().out
