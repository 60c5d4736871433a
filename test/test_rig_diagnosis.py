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
import pytest
from conftest import background, gather
from scipy.stats import t

from rig_identification.cli.diagnose import print_rig_diagnosis_text
from rig_identification.design.scenarios import simulate_random
from rig_identification.diagnosis.rig_diagnosis import apart_advice, measured_values, physical_starts
from rig_identification.estimation.harmonic_start import damped_start, drag_start
from rig_identification.estimation.rig_fit import REWEIGHT_LIMIT, SANDWICH_BLOCKS
from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import entry_scales
from rig_identification.pipeline.rig_model import LEVEL_LIMIT, fit_whole_recording, prepared
from rig_identification.report.rig_page import diagnosis_html

DELAY = 0.008
ROTOR_MASS = 10.0
DRAG = 5000.0
PINS = 1e-3         # m: μ r of the ceiling pins (0.08 × 12 mm)
GYRO_BIAS = [0.003, -0.002, 0.004]      # rad/s, IMU axes
#: A bias's error over its σ (12 blocks' means: Student's t, 11 degrees of freedom) within this at 99.9 %.
T999 = float(t.ppf(0.9995, SANDWICH_BLOCKS - 1))


def _diagnosed(seed: int, effects: list, seconds: float):
    """Job: a random 4-cable 'wide' rig (``seed``) with ``effects`` concealed, fitted and diagnosed;
    the truth, the JSON and ``rig-identify diagnose``'s text output."""
    _, sim = simulate_random(seed, 4, "wide", effects, seconds)
    res = fit_whole_recording(Recording(sim.rig, sim.sensors, sim.truth, None))
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        print_rig_diagnosis_text(res)
    return sim.truth, res.to_dict(), text.getvalue()


def _drag_start(seed: int, seconds: float):
    """Job: bench_trust's air-drag rig (``seed``) with a drag of :data:`DRAG` on both terms; the
    undamped and the damped forced response's misfits, the drag start and the air drag's physical
    start the diagnosis would take."""
    _, sim = simulate_random(seed, 4, "wide", [{"name": "air_drag", "linear": DRAG, "angular": DRAG}], seconds)
    inp = prepared(Recording(sim.rig, sim.sensors, sim.truth, None))      # the fit's starts, as inertia makes them
    damped = damped_start(inp.rc, sim.rig, inp.prior, inp.forced)
    physical = physical_starts(inp.rc, damped)["air_drag"]
    return inp.forced.level, damped.level, drag_start(inp.rc, damped), physical.values


def _rotor_absent(seed: int, seconds: float):
    """Job: the rotor's rig (``seed``) without a rotor, fitted with exciter_rotor from the
    unbalance its force gives (as the diagnosis's restart would): what the force measures of the
    unbalance at that fit, the fitted rotor's values and σ, the fit's worst channel over its noise."""
    _, sim = simulate_random(seed, 4, "wide", [], seconds)
    inp = prepared(Recording(sim.rig, sim.sensors, sim.truth, None))
    fit = inp.fit({"exciter_rotor": physical_starts(inp.rc)["exciter_rotor"].values})
    values, std = fit.extension("exciter_rotor")
    measured = measured_values(inp.rc, inp.prior, fit)["exciter_rotor"]
    return measured, values, std, float(np.max(fit.residual_level))


background("rig_diagnosis", __file__, _diagnosed, {
    "delay": (7001, [{"name": "sensor_delay", "stream": "load_cells", "delay": DELAY}], 20.0),
    # 7002: the exciter's spin axis vertical, so its unbalance's weight makes a rotating moment
    "rotor": (7002, [{"name": "exciter_rotor", "rotor_mass": ROTOR_MASS}], 20.0),
    # and a constant gyro bias (the fit removes each channel's offset: the pins' fit is as without it)
    "pins": (7003, [{"name": "pivot_friction", "mu_r": PINS}, {"name": "gyro_bias", "bias": GYRO_BIAS}], 20.0),
}, first=True)
background("drag_start", __file__, _drag_start, {"drag": (8500, 30.0)})
background("rotor_absent", __file__, _rotor_absent, {"clean": (7002, 20.0)})


def test_a_load_cell_delay_is_named_fitted_and_the_tensor_corrected():
    """An 8 ms delay of the load cells (20 s): the rigid-body rig model does not find the motion
    (its tensions 150–220× their noise); the diagnosis names load_cell_delay, told apart from
    every other extension, and nothing else; the refit gives the delay within 3 σ and 0.2 ms, every channel
    within 1.5× its noise (the exciter's too: its σ from its samples as read, not from the grid
    of the late load cells), and every tensor entry within 1 % and 3 σ."""
    truth, d, _ = gather("rig_diagnosis", "delay")["delay"]
    dg = d["diagnosis"]
    assert dg["named"] == ["load_cell_delay"] and dg["extensions"] == ["load_cell_delay"], dg["steps"]
    before = dg["residual_level_before"]
    assert min(v for c, v in before.items() if c.startswith("tension")) > 10, before
    ext = d["extensions"]["load_cell_delay"]
    assert abs(ext["values"][0] - DELAY) < max(3 * ext["std"][0], 2e-4), ext
    after = dg["residual_level_after"]
    assert all(v < LEVEL_LIMIT for v in after.values()) and d["verdict"] == "ok", (after, d["verdict"])
    tru = np.array([truth["inertia_about_cg"][k] for k in KEYS])
    est = np.array([d["inertia_about_cg"][k] for k in KEYS])
    sd = np.array([d["inertia_std"][k] for k in KEYS])
    assert np.all(np.abs(est - tru) < 0.01 * entry_scales(tru)), (est - tru) / entry_scales(tru)
    assert np.all(np.abs(est - tru) < 3 * sd), (est - tru) / sd


def test_an_exciter_rotor_is_named_and_the_body_given_without_it():
    """A 10 kg rotor rides on the exciter's bearing (the cables carry it; rig.yaml and the truth
    give the body without it; the exciter's load cells read its inertial force) and spins about a
    vertical axis (its unbalance's weight a moment turning with it): the rigid-body model does not
    find the motion (a channel beyond 10× its noise); the model with exciter_rotor finds it — added
    by its test, or, where the tests do not find it, fitted from the unbalance the measured force
    gives — and the diagnosis names exciter_rotor and nothing else, told apart from every other extension in its
    place; the refit gives the rotor's mass within 3 σ and 2 %, explains every channel, and the
    body less the rotor — mass, CG and every tensor entry — is the truth's within 3 σ (and 1 % for
    the tensor); the rotor's mass and CG are not reported as rig.yaml's errors."""
    truth, d, text = gather("rig_diagnosis", "rotor")["rotor"]
    dg = d["diagnosis"]
    assert dg["named"] == ["exciter_rotor"] and dg["extensions"] == ["exciter_rotor"], dg["steps"]
    assert max(dg["residual_level_before"].values()) > REWEIGHT_LIMIT, dg["residual_level_before"]
    assert not dg["steps"][0]["restart"] or "fitted again with exciter_rotor from the value the recording gives" in text
    # the unbalance the motion asks for is the one the force on the body measures, the truth's within 0.5 %
    assert dg["confirmed"] == ["exciter_rotor"], dg["steps"][0]
    excitation = truth["simulator"]["excitation"]
    unbalance = excitation["amplitude"] / (2 * np.pi * excitation["frequency"]) ** 2
    assert abs(dg["steps"][0]["measured"]["0"] - unbalance) < 0.005 * unbalance, (dg["steps"][0]["measured"], unbalance)
    assert all(v < LEVEL_LIMIT for v in dg["residual_level_after"].values()) and d["verdict"] == "ok"
    mass, mass_std = d["extensions"]["exciter_rotor"]["values"][1], d["extensions"]["exciter_rotor"]["std"][1]
    assert abs(mass - ROTOR_MASS) < min(3 * mass_std + 1e-3, 0.02 * ROTOR_MASS), (mass, mass_std)
    assert d["exciter_rotor_removed_kg"] == mass
    assert abs(d["mass"] - truth["mass"]) < 3 * d["mass_std"], (d["mass"], truth["mass"], d["mass_std"])
    cg = d["center_of_gravity"]
    assert np.all(np.abs(np.subtract(cg["combined"], truth["center_of_gravity"])) < 3 * np.array(cg["combined_std"]))
    assert not [c for c in dg["data_errors"] if c["unknown"] in ("mass", "cg x", "cg y", "cg z")], dg["data_errors"]
    tru = np.array([truth["inertia_about_cg"][k] for k in KEYS])
    est = np.array([d["inertia_about_cg"][k] for k in KEYS])
    sd = np.array([d["inertia_std"][k] for k in KEYS])
    assert np.all(np.abs(est - tru) < 0.01 * entry_scales(tru)), (est - tru) / entry_scales(tru)
    assert np.all(np.abs(est - tru) < 3 * sd), (est - tru) / sd


def test_a_rotor_the_recording_lacks_falls_away_from_the_forces_unbalance():
    """The rotor's rig (vertical spin axis, 20 s) without its rotor, fitted with exciter_rotor
    from the unbalance the measured force gives (4.2 kg·m, as the diagnosis's restart does): the
    fit explains every channel and takes the unbalance to zero within 3 σ, far outside what would
    confirm the force's (confirms: within Z95 σ plus CONFIRM_SHARE of it) — a term that only
    soaks up a misfit is not named beside one."""
    from rig_identification.diagnosis.rig_diagnosis import confirms
    measured, values, std, worst = gather("rotor_absent")["clean"]
    assert measured[0] > 1.0 and worst < LEVEL_LIMIT, (measured, worst)
    assert abs(values[0]) < 3 * std[0], (values, std)
    assert not confirms(values, std, measured)


def test_dry_friction_in_the_ceiling_pins_is_named_fitted_and_the_tensor_corrected():
    """Dry friction in the ceiling anchors' pins (μ r = 1 mm: 0.08 on a 12 mm pin; 20 s) and a
    constant gyro bias: the rigid-body model does not explain the tensions (beyond 1.5× their
    noise); the diagnosis names pivot_friction, told apart from every other extension and from the
    body's viscous damping (at one amplitude an equivalent damping), and the gyro's bias, and
    nothing else; the bias within Student's t at 99.9 % of its σ of the truth and its σ within a
    factor 2 of the white noise's σ/√m; the refit gives μ r within 3 σ and 2 %, explains every
    channel within 1.5× its noise, and every tensor entry it determines is the truth's within 1 %
    and 3 σ.  (The delay's and the rotor's rigs, without a bias, name none.)"""
    truth, d, text = gather("rig_diagnosis", "pins")["pins"]
    dg = d["diagnosis"]
    assert dg["named"] == ["pivot_friction", "gyro_bias"] and dg["extensions"] == ["pivot_friction"], dg["steps"]
    bias = dg["gyro_bias"]
    err = np.subtract(bias["values"], GYRO_BIAS)
    assert np.all(np.abs(err) < T999 * np.array(bias["std"])), (err, bias)
    sim = truth["simulator"]
    white = sim["sensor_noise_sigma"]["gyro"] / np.sqrt(d["window"]["duration_s"] * sim["sensor_rates_hz"]["imu"])
    assert np.all((np.array(bias["std"]) > white / 2) & (np.array(bias["std"]) < 2 * white)), (bias["std"], white)
    assert "gyro_bias named" in text
    before = dg["residual_level_before"]
    assert max(v for c, v in before.items() if c.startswith("tension")) > LEVEL_LIMIT, before
    ext = d["extensions"]["pivot_friction"]
    assert abs(ext["values"][0] - PINS) < min(3 * ext["std"][0] + 1e-7, 0.02 * PINS), ext
    assert all(v < LEVEL_LIMIT for v in dg["residual_level_after"].values()), dg["residual_level_after"]
    tru = np.array([truth["inertia_about_cg"][k] for k in KEYS])
    est = np.array([d["inertia_about_cg"][k] for k in KEYS])
    sd = np.array([d["inertia_std"][k] for k in KEYS])
    given = np.array([k not in d["undetermined"] + d["ambiguous"] for k in KEYS])
    assert given.sum() >= 3, (d["verdict"], d["undetermined"], d["ambiguous"])
    assert np.all(np.abs(est - tru)[given] < 0.01 * entry_scales(tru)[given]), (est - tru) / entry_scales(tru)
    assert np.all(np.abs(est - tru)[given] < 3 * sd[given]), (est - tru) / sd


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
    lost = SimpleNamespace(residual_level=np.array([0.98, 318.3, 11.0]), offsets=None, offset_std=None,
                           channels=("gyro_x", "tension:c0", "gyro_y"))
    dg = RigDiagnosis((), None, (), lost, None)
    assert not dg.found_motion and dg.named == () and dg.advice == [] and dg.to_dict()["found_motion"] is False
    print_diagnosis(dg)
    out = capsys.readouterr().out
    assert "did not find the motion" in out and "nothing is named" in out and "explains" not in out, out
    fits = SimpleNamespace(residual_level=np.array([0.98, 1.2, 1.0]), offsets=None, offset_std=None,
                           channels=lost.channels)
    assert RigDiagnosis((), None, (), fits, None).found_motion
    print_diagnosis(RigDiagnosis((), None, (), fits, None))
    assert "the model explains the recording" in capsys.readouterr().out


def test_an_extension_that_lowers_a_misfit_it_does_not_explain_is_not_named(capsys):
    """An extension added where the refit still leaves a channel beyond 1.5× its noise (the fit's
    own model_error: on the package's simulator an 8 Hz structural mode took imu_offset and
    gyro_scale) stays in the model but is not named, nor its class, nor viscous damping; the
    advice says what is left unexplained.  With every channel fitted the same step is named."""
    from types import SimpleNamespace

    from rig_identification.cli.rig_model import print_diagnosis
    from rig_identification.diagnosis.rig_diagnosis import Candidate, Damping, RigDiagnosis, Step
    channels = ("tension:c0", "gyro_x", "gyro_y")
    rigid = SimpleNamespace(residual_level=np.array([4.0, 6.1, 3.2]), offsets=None, offset_std=None, channels=channels)
    cand = Candidate("imu_offset", 120.0, 3, 16.3, np.array([0.01, 0.0, 0.02]), np.full(3, 1e-3),
                     np.array([40.0, 50.0]), True)
    step = Step("imu_offset", "imu_offset", (), {}, (cand,))
    damping = Damping(np.array([5.0, 0.5]), {"air_drag": 3.0, "pivot_friction": 4.0}, (), np.array([9.0, 14.0]))
    after = SimpleNamespace(residual_level=np.array([1.1, 2.3, 1.2]), offsets=None, offset_std=None, channels=channels)
    dg = RigDiagnosis((), damping, (step,), rigid, after)
    assert dg.found_motion and not dg.explained and dg.unexplained == ("gyro_x",)
    assert dg.extensions == ("imu_offset",) and dg.named == () and dg.classes == ()
    assert len(dg.advice) == 1 and "gyro_x" in dg.advice[0] and "nothing is named" in dg.advice[0], dg.advice
    d = dg.to_dict()
    assert d["explained"] is False and d["named"] == [] and d["unexplained_channels"] == ["gyro_x"]
    fitted = SimpleNamespace(residual_level=np.array([1.1, 1.3, 1.2]), offsets=None, offset_std=None, channels=channels)
    good = RigDiagnosis((), damping, (step,), rigid, fitted)
    assert good.explained and good.named == ("imu_offset", "viscous_damping") and good.advice == []
    # a significant damping that fails an extension's other tests is no name and no class: negative beyond
    # 3 σ (it puts energy in), or not lowering χ² on the half of the record it was not fitted on
    for bad in (Damping(np.array([10.4, -3.3]), {"air_drag": 0.5}, ("air_drag",), np.array([9.0, 14.0])),
                Damping(np.array([10.4, 1.0]), {"air_drag": 0.5}, ("air_drag",), np.array([9.0, -2.0]))):
        assert not bad.found and bad.significance[0] == 10.4
        dg_bad = RigDiagnosis((), bad, (), rigid, None)
        clean = RigDiagnosis((), bad, (), fitted, None)
        assert clean.explained and clean.named == () and clean.classes == () and clean.advice == [], clean.advice
        assert dg_bad.to_dict()["damping"]["found"] is False
    told = Damping(np.array([10.4, 1.0]), {"air_drag": 0.5}, ("air_drag",), np.array([9.0, 2.0]))
    assert RigDiagnosis((), told, (), fitted, None).classes == (("viscous_damping", "air_drag"),)
    unsure = RigDiagnosis((), damping, (Step("imu_offset", "imu_offset", ("gyro_scale",), {"gyro_scale": 1.0},
                                             (cand,)),), rigid, fitted)
    assert unsure.classes == (("imu_offset", "gyro_scale"),)
    assert "another exciter frequency" in unsure.advice[0] and "ω² times" in unsure.advice[0], unsure.advice
    # what tells a class apart follows its members' physics: a common event aligns two clocks,
    # a second amplitude the dampings; a pair with nothing particular gets the plan's run
    assert "tap on the frame" in apart_advice(("load_cell_delay", "exciter_delay"))
    assert "second forcing amplitude" in apart_advice(("viscous_damping", "air_drag", "pivot_friction"))
    mixed = apart_advice(("exciter_rotor", "imu_offset", "exciter_delay"))
    assert mixed.count("tells exciter_rotor from imu_offset, exciter_delay") == 1 and "rig-identify plan" in mixed
    # the text: the step added, not named (the refit's extension values are not printed: no refit record)
    dg_text = RigDiagnosis((), None, (step,), rigid, None)
    print_diagnosis(dg_text)
    out = capsys.readouterr().out
    assert "imu_offset: χ² falls 120 (threshold 16.3), cross-validated; added, not named" in out, out


def test_a_restarts_extension_that_another_sensor_confirms_is_named_beside_a_misfit(capsys):
    """The rotor found where the rigid-body fit lost the motion, its unbalance in the last fit
    (3.72 ± 0.07 kg·m) the one the exciter's force measures (3.73): named though the fit with it
    leaves the tensions 3.5× their noise (the shared recording's case), and the advice says both;
    a second extension the refit added beside it is not named.  With the fit's unbalance off the
    force's (4.0 ± 0.07), nothing measured, or the step not told apart, it is not named; nor where
    the motion is still lost.  confirms: within Z95 σ plus CONFIRM_SHARE of the measured value."""
    from types import SimpleNamespace

    from rig_identification.cli.rig_model import print_diagnosis
    from rig_identification.diagnosis.rig_diagnosis import Candidate, RigDiagnosis, Step, confirms
    channels = ("tension:c0", "gyro_x")
    rigid = SimpleNamespace(residual_level=np.array([513.0, 40.0]), offsets=None, offset_std=None, channels=channels)

    def fit(unbalance, level=3.5):
        return SimpleNamespace(residual_level=np.array([level, 1.05]), offsets=None, offset_std=None,
                               channels=channels, extension=lambda name: (np.array([unbalance, 11.06]),
                                                                          np.array([0.07, 0.07])))

    def rotor(measured=True, close=()):
        cand = Candidate("exciter_rotor", 5e6, 2, 13.8, np.array([3.7, 11.0]), np.array([0.07, 0.07]),
                         np.array([2e6, 2e6]), True)
        return Step("exciter_rotor", "exciter_rotor", close, {}, (cand,), restart=True,
                    measured={0: 3.73} if measured else {})
    drag = Step("air_drag", "air_drag", (), {}, (Candidate("air_drag", 40.0, 2, 13.8, np.array([5.0, 1.0]),
                                                           np.array([1.0, 1.0]), np.array([3.0, 4.0]), True),))
    dg = RigDiagnosis((), None, (rotor(), drag), rigid, fit(3.72))
    assert not dg.explained and dg.named == ("exciter_rotor",) and dg.confirmed == ("exciter_rotor",), dg.named
    assert dg.classes == () and "nothing else is named" in dg.advice[0] and "tension:c0" in dg.advice[0], dg.advice
    assert "3.72 ± 0.07 kg·m of unbalance, the exciter's force on the body over Ω² gives 3.73" in dg.advice[1], \
        dg.advice
    assert dg.to_dict()["confirmed"] == ["exciter_rotor"] and dg.to_dict()["named"] == ["exciter_rotor"]
    print_diagnosis(dg)
    out = capsys.readouterr().out
    assert "cross-validated; named: the force measures it" in out and "air_drag: χ² falls 40" in out, out
    for other, after in ((rotor(), fit(4.0)), (rotor(measured=False), fit(3.72)),
                         (rotor(close=("imu_offset",)), fit(3.72)), (rotor(), fit(3.72, level=30.0))):
        assert RigDiagnosis((), None, (other, drag), rigid, after).named == (), other
    assert confirms(np.array([3.86]), np.array([0.05]), {0: 3.73})            # 0.13 ≤ 1.96·0.05 + 0.0373
    assert not confirms(np.array([3.87]), np.array([0.05]), {0: 3.73}) and not confirms(np.ones(1), np.ones(1), {})


def test_a_candidate_is_eligible_only_where_the_recording_determines_one_of_its_values():
    """A 2-unknown quadratic drag whose joint fall of χ² just passes the 0.999 quantile (13.9 >
    13.8) with each value within 3.29 σ (2.4 σ and 2.9 σ: what the package's clean, undetermined
    near-parallel rig 7501 gave) is not a candidate; the same fall with one value at 3.5 σ is."""
    from rig_identification.diagnosis.rig_diagnosis import DETERMINED_Z, Candidate
    assert DETERMINED_Z == pytest.approx(3.2905, abs=1e-4)
    weak = Candidate("air_drag", 13.95, 2, 13.82, np.array([1466.0, 556.6]), np.array([611.4, 190.8]),
                     np.array([3.9, 0.5]), True)
    assert weak.significant and weak.cross_validated and weak.plausible and not weak.determined
    assert not weak.eligible and weak.to_dict()["determined"] is False
    firm = Candidate("air_drag", 13.95, 2, 13.82, np.array([1466.0, 667.8]), np.array([611.4, 190.8]),
                     np.array([3.9, 0.5]), True)
    assert firm.determined and firm.eligible


def test_the_dampings_alternatives_leave_out_one_the_model_already_holds():
    """Where a step added pivot_friction (the ceiling pins' dry friction), the
    viscous damping's alternatives are those the linearisation still tests — air_drag alone —
    not the friction the model holds beside it (it asked for its column and raised KeyError)."""
    from types import SimpleNamespace

    from rig_identification.diagnosis.rig_diagnosis import damping_alternatives
    asked = []

    class Lin:
        names = ("air_drag", "load_cell_delay")

        def without(self, index):
            return self

        def base(self):
            return "base"

        def fitted(self, names):
            asked.append(names)
            return names

        def vuong(self, a, b):
            return 5.0

        def held_out(self, index):
            return np.array([3.0, 4.0])

    lay = SimpleNamespace(body_damping=slice(0, 2))
    fit = SimpleNamespace(layout=lay, parameters=SimpleNamespace(body_damping=np.array([150.0, 300.0])),
                          covariance=np.diag([1.0, 4.0]))
    d = damping_alternatives(Lin(), fit)
    assert asked == [("air_drag",)] and d.alternatives == {"air_drag": 5.0} and d.indistinguishable == ()
    np.testing.assert_allclose(d.significance, [150.0, 150.0])
    assert d.found and d.plausible and d.cross_validated


def test_no_extension_is_tested_where_the_fit_leaves_the_tensor_undetermined(monkeypatch):
    """A fit that explains the recording but leaves the tensor undetermined (verdict
    not_identifiable) sits at one of many estimates along its undetermined directions:
    diagnose_rig tests no extension there and refits nothing, but reads what the model holds —
    its viscous damping against quadratic drag and the pins' friction in its place (the
    linearisation asked for those two alone; not where another minimum fits as well) and the
    gyro's bias from the fit's offsets — and names those it finds (the report's page says so
    too); the advice says why nothing else is tested."""
    from types import SimpleNamespace

    from rig_identification.diagnosis import rig_diagnosis as rd
    asked = []

    class Lin:
        def __init__(self, rec, prior, fit, names):
            asked.append(names)
            self.names = names

        def without(self, index):
            return self

        def base(self):
            return "base"

        def fitted(self, names):
            return names

        def vuong(self, a, b):
            return 5.0

        def held_out(self, index):
            return np.array([3.0, 4.0])

    def refit(extensions, start, stiffness):
        raise AssertionError("no refit where the tensor is not determined")
    monkeypatch.setattr(rd, "LinearisedRig", Lin)
    monkeypatch.setattr(rd, "next_step", lambda lin: pytest.fail("an extension tested at an undetermined tensor"))
    channels = ("tension:c0", "gyro_x", "gyro_y", "gyro_z")
    fit = SimpleNamespace(unknowns=None, residual_level=np.array([1.0, 1.02, 0.98, 1.01]), channels=channels,
                          determined=False, ambiguous=[], layout=SimpleNamespace(body_damping=slice(0, 2)),
                          parameters=SimpleNamespace(body_damping=np.array([180.0, 320.0])),
                          covariance=np.diag([1.7, 210.0]), offsets=np.array([12.0, -0.003, 2e-5, 0.004]),
                          offset_std=np.array([0.01, 2e-5, 2e-5, 2e-5]))
    dg = rd.diagnose_rig(None, None, fit, ["c0"], refit)
    assert asked == [("air_drag", "pivot_friction")]
    assert dg.steps == () and dg.refit is None and not dg.determined
    assert dg.damping.found and dg.damping.alternatives == {"air_drag": 5.0, "pivot_friction": 5.0}
    np.testing.assert_allclose(dg.gyro.values, [-0.003, 2e-5, 0.004])
    assert dg.named == ("viscous_damping", "gyro_bias") and dg.classes == ()
    assert len(dg.advice) == 1 and "not determined" in dg.advice[0] and "no extension is tested" in dg.advice[0]
    assert dg.to_dict()["determined"] is False and dg.to_dict()["gyro_bias"]["found"]
    html = diagnosis_html(SimpleNamespace(diagnosis=dg))
    assert "Gyro bias" in html and "-0.003 ± 2e-05" in html and "(named)" in html
    # another minimum as likely (Ixx, Iyy ambiguous): the damping there may make up for the
    # tensor's error, so it is not read; the gyro's bias, independent of the minimum, still is
    asked.clear()
    dg = rd.diagnose_rig(None, None, SimpleNamespace(**{**vars(fit), "ambiguous": [0, 1]}), ["c0"], refit)
    assert asked == [] and dg.damping is None and dg.named == ("gyro_bias",)


def test_a_gyro_bias_is_found_where_its_mean_stands_out_of_the_blocks_scatter():
    """The offset the fit removes and its σ from the blocks' means (channel_offsets): on white
    noise (σ 2 mrad/s, 18 000 samples) σ is the white noise's σ/√m (within the scatter of a σ
    from 12 blocks' means), and a bias of
    0.2 mrad/s (13 σ) is found, within Student's t at 99.9 % of its σ, while none is not; a random
    walk of 1e-4 rad/s/√s (no constant bias)
    widens σ to the walk's scatter, so its mean is not read as a bias."""
    from rig_identification.diagnosis.rig_diagnosis import GyroBias
    from rig_identification.estimation.rig_fit import channel_offsets

    rng = np.random.default_rng(5)
    m = 18000
    white = 0.002 * rng.standard_normal((m, 3))
    off, sd = channel_offsets(white + [2e-4, 0.0, 0.0])
    ratio = sd / (0.002 / np.sqrt(m))           # √(χ²₁₁/11): within 0.45–1.8 at 99.9 %
    assert np.all((ratio > 0.45) & (ratio < 1.8)), ratio
    assert np.all(np.abs(off - [2e-4, 0.0, 0.0]) < T999 * sd)
    assert GyroBias(off, sd).found and not GyroBias(*channel_offsets(white)).found
    walk = np.cumsum(1e-4 * np.sqrt(1 / 200) * rng.standard_normal((m, 3)), axis=0)
    off, sd = channel_offsets(walk + white)
    assert np.all(sd > 2 * 0.002 / np.sqrt(m)), (off, sd)


def test_no_name_where_the_rigid_model_restarted_from_the_extended_fit_explains_every_channel(monkeypatch):
    """An extension found at a rigid fit that misfits, whose refit leaves the tensor undetermined:
    the rigid-body model is fitted again from the refit's tensor.  Where that explains every
    channel, the misfit was the first descent's (another minimum of a flat likelihood), so nothing
    is named and that rigid fit is reported; where it still misfits, the extension is named."""
    from types import SimpleNamespace

    from rig_identification.diagnosis import rig_diagnosis

    def fake(level, extensions=(), determined=True):
        return SimpleNamespace(residual_level=np.array(level), channels=("tension:c0", "gyro_x"), unknowns=None,
                               determined=determined, parameters=SimpleNamespace(inertia=np.arange(6.0)),
                               layout=SimpleNamespace(extensions=extensions), offsets=None, offset_std=None)
    step = SimpleNamespace(added="load_cell_delay", best="load_cell_delay", named=True, indistinguishable=())
    lin = SimpleNamespace(fitted=lambda names: SimpleNamespace(of=lambda e: np.array([0.008])))
    monkeypatch.setattr(rig_diagnosis, "LinearisedRig", lambda rec, prior, current, untried: lin)
    monkeypatch.setattr(rig_diagnosis, "damping_alternatives", lambda lin, fit: None)
    monkeypatch.setattr(rig_diagnosis, "measured_values", lambda rec, prior, fit: {})
    rigid = fake([2.4, 1.0])
    extended = fake([1.0, 1.0], ("load_cell_delay",), determined=False)
    for again_level, named in (([1.1, 1.0], ()), ([1.8, 1.0], ("load_cell_delay",))):
        again = fake(again_level)
        calls = []

        def refit(extensions, start, stiffness):
            calls.append((tuple(extensions), start))
            return extended if extensions else again
        steps = iter([step])
        monkeypatch.setattr(rig_diagnosis, "next_step", lambda lin: next(steps, None))
        dg = rig_diagnosis.diagnose_rig(None, None, rigid, ["c0"], refit)
        assert [c[0] for c in calls] == [("load_cell_delay",), ()], calls
        assert dg.named == named, (again_level, dg.named)
        if named:
            assert dg.refit is extended and dg.rigid is rigid and dg.determined
        else:
            assert dg.refit is None and dg.rigid is again and not dg.determined and "not determined" in dg.advice[0]


def test_no_name_where_a_fresh_start_not_the_extension_found_the_motion_the_rigid_fit_lost(monkeypatch):
    """The first rigid-body fit lost the motion (a channel 40× its noise) and the refit with the
    extension its tests added found it, the tensor determined: where the extension is not
    determined at the refit (−1.1 σ: bench_any_rig's clean 21138 and its load_cell_delay) the
    rigid-body model is fitted again from the refit's tensor, and where that explains every channel
    nothing is named; where the extension is determined (30 σ) it is named without that refit."""
    from types import SimpleNamespace

    from rig_identification.diagnosis import rig_diagnosis

    def fake(level, extensions=(), z=0.0):
        return SimpleNamespace(residual_level=np.array(level), channels=("tension:c0", "gyro_x"), unknowns=None,
                               determined=True, parameters=SimpleNamespace(inertia=np.arange(6.0)),
                               layout=SimpleNamespace(extensions=extensions), offsets=None, offset_std=None,
                               extension=lambda name: (np.array([z * 1e-4]), np.array([1e-4])))
    step = SimpleNamespace(added="load_cell_delay", best="load_cell_delay", named=True, indistinguishable=())
    lin = SimpleNamespace(fitted=lambda names: SimpleNamespace(of=lambda e: np.array([-0.036])))
    monkeypatch.setattr(rig_diagnosis, "LinearisedRig", lambda rec, prior, current, untried: lin)
    monkeypatch.setattr(rig_diagnosis, "damping_alternatives", lambda lin, fit: None)
    monkeypatch.setattr(rig_diagnosis, "measured_values", lambda rec, prior, fit: {})
    rigid = fake([40.0, 3.0])
    again = fake([1.0, 1.0])
    cases = ((-1.1, (), [("load_cell_delay",), ()]), (30.0, ("load_cell_delay",), [("load_cell_delay",)]))
    for z, named, fits in cases:
        extended = fake([1.0, 1.0], ("load_cell_delay",), z)
        calls = []

        def refit(extensions, start, stiffness):
            calls.append(tuple(extensions))
            return extended if extensions else again
        steps = iter([step])
        monkeypatch.setattr(rig_diagnosis, "next_step", lambda lin: next(steps, None))
        dg = rig_diagnosis.diagnose_rig(None, None, rigid, ["c0"], refit)
        assert calls == fits, (z, calls)
        assert dg.named == named, (z, dg.named)
        assert (dg.rigid is again and dg.refit is None) if not named else (dg.refit is extended), z


def test_the_rotor_fitted_from_its_unbalance_is_named_only_where_it_finds_the_motion_and_is_told_apart(monkeypatch):
    """Where the rigid-body fit lost the motion, the rotor is fitted from the unbalance the
    measured force gives (its mass 0): no step where that fit loses it too or the recording gives
    no unbalance; where it finds it, the rotor is the step (restart) when its fall of χ² without
    it is significant and it is determined, and a class where an eligible extension in its place
    fits as well (Vuong's z below Student's t)."""
    from types import SimpleNamespace

    from rig_identification.diagnosis import rig_diagnosis
    from rig_identification.estimation.rig_extensions import ExtensionFit
    from rig_identification.estimation.rig_unknowns import EXTENSIONS, Layout

    lay = Layout(1, extensions=("exciter_rotor",))
    every = lay.extended(tuple(EXTENSIONS))        # the linearisation's layout: every untried extension
    rotor = every.extension_of("exciter_rotor")

    def found(level):
        return SimpleNamespace(residual_level=np.array(level), layout=lay, covariance=np.eye(lay.size) * 1e-4,
                               parameters=SimpleNamespace(inertia=np.arange(6.0)))

    def ext(name, statistic, value):
        return ExtensionFit((name,), statistic, 2, np.full(2, value), np.full(2, 0.01), np.full(2, value),
                            np.array([9.0, 9.0]), np.zeros(4))

    class Lin:
        def __init__(self, r, z, unbalance=4.0):
            self.r, self.rows, self.names, self.z = r, 4, ("air_drag",), z
            self.x = np.zeros(every.size)
            self.x[rotor] = [unbalance, 10.0]

        def without(self, index):
            assert index == rotor
            return Lin(np.full(6, 30.0), self.z)

        def held_out(self, index):
            return np.array([50.0, 50.0])

        def fitted(self, names):
            return ext(names[0], 900.0, 0.5)

        def vuong(self, a, b):
            return self.z

    rec = SimpleNamespace(unbalance=lambda: 4.0)
    lost = SimpleNamespace(parameters=SimpleNamespace(inertia=np.arange(6.0)))
    calls = []

    def refit(extensions, start, stiffness):
        calls.append({e: v.tolist() for e, v in extensions.items()})
        return after
    for after_level, z, expected, unbalance in (([1.0, 1.1], 9.0, ((), True), 4.0),
                                                ([1.0, 1.1], 0.5, (("air_drag",), True), 4.05),
                                                ([1.0, 40.0], 9.0, None, 4.0)):
        after = found(after_level)
        monkeypatch.setattr(rig_diagnosis, "LinearisedRig",
                            lambda rec_, prior, fit, untried, z=z, u=unbalance: Lin(np.ones(6), z, u))
        got = rig_diagnosis.restart_step(rec, None, lost, refit)
        assert calls[-1] == {"exciter_rotor": [4.0, 0.0]}, calls
        if expected is None:
            assert got is None
            continue
        step, fit = got
        assert fit is after and step.added == "exciter_rotor" and step.restart == expected[1]
        assert step.indistinguishable == expected[0] and step.named == (not expected[0]), step
        own = next(c for c in step.candidates if c.name == "exciter_rotor")
        assert own.statistic == pytest.approx(6 * 30.0 ** 2 - 6.0) and own.eligible
    assert rig_diagnosis.restart_step(SimpleNamespace(unbalance=lambda: None), None, lost, refit) is None


def test_a_strongly_damped_body_gets_its_drag_start_from_the_damped_forced_response():
    """Strong air drag (bench_trust's air_drag row, 30 s): the undamped forced response misses the
    fundamental beyond its σ (the noise and the linearisation's share of each amplitude), the
    forced response fitted with the body's damping within it, and the quadratic drag equivalent to
    that damping at the record's amplitudes (the restart's start where the rigid fit does not find
    the motion) is positive on both terms and its angular term within a factor 2 of the truth,
    where the motion is mostly a rotation (the linear term rests on the CG's small swing: only a
    start)."""
    forced_level, damped_level, start, physical = gather("drag_start")["drag"]
    assert forced_level > 1.5 and damped_level < min(1.0, 0.6 * forced_level), (forced_level, damped_level)
    assert np.all(start > 0) and 0.5 < start[1] / DRAG < 2.0, start
    np.testing.assert_array_equal(physical, start)
