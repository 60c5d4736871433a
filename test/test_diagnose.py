"""diagnose: each effect of the library, concealed in a simulated recording (random vehicle
and rig geometry, realistic noise), is named first, its parameters estimated within 15 %,
the residuals of the channels it affects reduced by ≥ 30 % and the inertia brought back
within the identification bounds (diagonal 0.5 %, products 0.5 % of the largest diagonal,
3 σ).  Clean recordings give no mismatch; the thesis's model misses the gyroscopic
coupling (on a planned run: its effect is the residual's part locked to the forcing); the reference
damped recording's damping is named with its coefficients.

The simulations and diagnoses are background jobs (conftest.background): they start in a
worker process when the session starts and this module runs last.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from conftest import background, gather, recording

DEFAULT = "config/rigs/default.yaml"
DURATION = 60.0

# effect, the channel group it affects, and how its parameters are checked
CASES = {
    "viscous_damping": ({"name": "viscous_damping", "linear": 150.0, "angular": 300.0}, "gyro"),
    "air_drag": ({"name": "air_drag", "linear": 5000.0, "angular": 5000.0}, "gyro"),
    "coulomb_friction": ({"name": "coulomb_friction", "torque": 4.0, "force": 10.0}, "gyro"),
    "exciter_rotor": ({"name": "exciter_rotor"}, "gyro"),
    "imu_offset": ({"name": "imu_offset", "offset": [0.05, -0.03, 0.10]}, "accel"),
    "imu_misalignment": ({"name": "imu_misalignment", "rpy": [0.01, -0.015, 0.02]}, "accel"),
    "sensor_delay": ({"name": "sensor_delay", "stream": "load_cells", "delay": 0.02}, "gyro"),
    "gyro_bias": ({"name": "gyro_bias", "bias": [0.003, -0.002, 0.004]}, "gyro"),
    "accelerometer_bias": ({"name": "accelerometer_bias", "bias": [0.05, -0.03, 0.08]}, "accel"),
    "cable_elasticity": ({"name": "cable_elasticity", "stiffness": 2.0e6, "declared_stiffness": 5.0e6}, "accel"),
    "load_cell_scale": ({"name": "load_cell_scale", "cable": "c1", "scale": 1.03}, "torque"),
    "cable_mass": ({"name": "cable_mass", "mass": 3.0}, "torque"),
    "body_mass": ({"name": "body_mass", "mass_error": 6.0}, "accel"),
    # rig.yaml's CG 46 mm off (a static test's error; screened with cg_free): the swinging body carries its CG
    "cg_offset": ({"name": "cg_offset", "offset": [0.01, -0.02, 0.04]}, "torque"),
}
def random_experiment(seed: int, effects: list, duration: float = DURATION) -> dict:
    """The default rig (thesis case 16, realistic sensors) with a random vehicle and geometry:
    mass ±25 %, principal moments ×0.8–1.25, small products, CG and anchors moved by
    centimetres, cable lengths ±5 cm, the exciter and the IMU moved."""
    rng = np.random.default_rng(seed)
    d = yaml.safe_load(open(DEFAULT))
    d["duration"], d["seed"], d["static"] = duration, int(seed), None
    rig = d["rig"]
    rig.pop("dummy_mass", None)
    rig["body"]["mass"] = float(rig["body"]["mass"] * rng.uniform(0.8, 1.25))
    cg = rng.uniform(-0.05, 0.05, 3)
    rig["body"]["center_of_gravity"] = cg.tolist()
    # the cable lengths are the anchor distances at a level pose of the body with its CG near
    # the middle of the ceiling anchors (as the thesis's cases), so every cable is taut
    p0 = np.array([1.6, 2.5, -2.58]) + np.r_[rng.uniform(-0.05, 0.05, 2), rng.uniform(-0.1, 0.1)]
    for c in rig["cables"]:
        c["body_anchor"] = (np.array(c["body_anchor"]) + rng.uniform(-0.05, 0.05, 3)).tolist()
        c["ceiling_anchor"] = (np.array(c["ceiling_anchor"]) + np.r_[rng.uniform(-0.1, 0.1, 2), 0.0]).tolist()
        c["length"] = float(np.linalg.norm(np.array(c["ceiling_anchor"]) - p0 - np.array(c["body_anchor"])))
    rig["exciter"]["position"] = (np.array(rig["exciter"]["position"]) + rng.uniform(-0.1, 0.1, 3)).tolist()
    rig["imu"]["position"] = (cg + rng.uniform(-0.2, 0.2, 3)).tolist()
    I = d["inertia_about_cg"]
    while True:
        ev = np.array([I["ixx"], I["iyy"], I["izz"]]) * rng.uniform(0.8, 1.25, 3)
        if ev[0] + ev[1] > ev[2] and ev[0] + ev[2] > ev[1] and ev[1] + ev[2] > ev[0]:
            break
    from scipy.spatial.transform import Rotation
    R = Rotation.from_rotvec(rng.uniform(-0.05, 0.05, 3)).as_matrix()
    J = R @ np.diag(ev) @ R.T
    d["inertia_about_cg"] = {"ixx": J[0, 0], "ixy": J[0, 1], "ixz": J[0, 2], "iyy": J[1, 1], "iyz": J[1, 2],
                             "izz": J[2, 2]}
    # the exciter between the two lowest natural frequencies, as in the thesis's case 16 (at a
    # mode, the 200 N would swing the body until a cable goes slack)
    from rig_identification.io.rig import rig_from_dict
    from rig_identification.model.modes import natural_modes
    r = rig_from_dict(rig, "random rig")
    f = sorted(m.frequency for m in natural_modes(r, r.mass, r.require_cg(), J, 5e6))
    d["excitation"]["rotating"]["frequency"] = float(0.5 * (f[0] + f[1]))
    d["effects"] = effects
    return d


def at_planned_amplitude(d: dict) -> dict:
    """``d`` with its exciter (position, spin axis, frequency kept) at the largest force the
    planner allows by its default limits (``rig-identify plan``: rotation ≤ 3°, every cable
    ≥ 20 % of its static tension; :func:`~rig_identification.design.planning.amplitude_at_limits`,
    noise-free 60 s simulations)."""
    from rig_identification.design.planning import Body, Run, amplitude_at_limits
    from rig_identification.model.simulator import experiment_from_dict
    exp = experiment_from_dict(d, "random")
    ex, n = d["excitation"]["rotating"], len(exp.rig.cables)
    body = Body(exp.rig, exp.mass, exp.inertia, np.broadcast_to(np.asarray(d["cable_model"]["stiffness"], float), (n,)),
                dict(d["sensors"]["rates_hz"]), dict(d["sensors"]["noise"]))
    run = Run(ex["frequency"], ex["amplitude"], tuple(d["rig"]["exciter"]["position"]), "z", 60.0, ex["ramp_time"],
              rpy=tuple(d["rig"]["exciter"].get("rpy", [0.0, 0.0, 0.0])), direction=ex["direction"])
    cand = amplitude_at_limits(body, run)
    assert cand is not None, "the planner found no amplitude within its limits"
    d["excitation"]["rotating"]["amplitude"] = float(cand.run.amplitude)
    return d


def simulate_taut(seed: int, effects: list, duration: float | None = None, planned: bool = False):
    """Simulate :func:`random_experiment` (``planned``: :func:`at_planned_amplitude`); a draw
    in which a cable goes slack (tension below 10 % of its share of the weight: beyond the
    rig's limits) is redrawn with the next seed.  Returns (experiment mapping, SimResult)."""
    from rig_identification.model.simulator import experiment_from_dict, simulate
    duration = DURATION if duration is None else duration
    for k in range(5):
        d = random_experiment(seed + 1000 * k, effects, duration)
        if planned:
            d = at_planned_amplitude(d)
        sim = simulate(experiment_from_dict(d, "random"))
        T = np.column_stack([sim.sensors.load_cells[n].data[:, 0] for n in sim.rig.cable_names])
        if T.min() > 0.1 * sim.rig.mass * sim.rig.gravity / T.shape[1]:
            return d, sim
    raise AssertionError(f"no taut random rig from seed {seed}")


def _run(seed, effects, model, duration, planned):
    """Job: simulate and diagnose; returns plain data (JSON-safe)."""
    from rig_identification.diagnosis.selection import diagnose
    from rig_identification.io.recording import Recording
    d, sim = simulate_taut(seed, effects, duration, planned)
    # rig.yaml's CG is screened where the lab asks for it (diagnose --cg-free): the cg_offset case
    cg_free = any(e["name"] == "cg_offset" for e in effects)
    out = diagnose(Recording(sim.rig, sim.sensors, sim.truth, "simulated"), model=model, cg_free=cg_free).to_dict()
    out["truth"] = sim.truth
    out["excitation"] = d["excitation"]["rotating"]
    return json.loads(json.dumps(out))


# the load cells and the exciter late together (one DAQ's clock 15 ms behind the IMU's)
DAQ_DELAY = [{"name": "sensor_delay", "stream": "load_cells", "delay": 0.015},
             {"name": "sensor_delay", "stream": "exciter", "delay": 0.015}]

# seed 100 + i per case, except body_mass: its seed 112 draws a rig on which a cable goes
# slack, and simulate_taut redraws it as 1112 (the same recording, one 60 s simulation less)
SEEDS = {"body_mass": 1112}


#: The library's slowest cases (35–70 s each) are measured by bench/bench_diagnose.py, with the
#: thesis model's gyroscopic coupling on a planned 120 s run, and left out of the suite.
BENCH_ONLY = ("load_cell_scale", "cg_offset", "cable_mass", "imu_misalignment")
SUITE_CASES = {k: v for k, v in CASES.items() if k not in BENCH_ONLY}


def _jobs() -> dict:
    """The fixture's simulations and diagnoses, the longest first (the exciter's rotor, the
    slowest to simulate)."""
    cases = {name: (SEEDS.get(name, 100 + i), [eff], "pem", DURATION, False)
             for i, (name, (eff, _)) in enumerate(CASES.items()) if name in SUITE_CASES}
    jobs = {}
    jobs["exciter_rotor"] = cases.pop("exciter_rotor")
    jobs.update(cases)
    jobs["clean"] = (301, [], "pem", DURATION, False)
    jobs["daq_delay"] = (302, DAQ_DELAY, "pem", DURATION, False)
    return jobs


background("diagnose", __file__, _run, _jobs(), first=True)


@pytest.fixture(scope="module")
def results():
    return gather("diagnose")


def _ratio(a, b) -> float:
    return float(np.linalg.norm(np.atleast_1d(np.asarray(a, float)))
                 / np.linalg.norm(np.atleast_1d(np.asarray(b, float))))


def _rel(est, true) -> float:
    est, true = np.atleast_1d(np.asarray(est, float)), np.atleast_1d(np.asarray(true, float))
    return float(np.linalg.norm(est - true) / np.linalg.norm(true))


def check_parameters(name: str, found: dict, truth_entry: dict, excitation: dict):
    p = found["parameters"]
    if name == "exciter_rotor":
        unbalance = excitation["amplitude"] / (2 * math.pi * excitation["frequency"]) ** 2
        assert _rel(p["unbalance"], unbalance) < 0.15, (p, unbalance)
    elif name == "sensor_delay":
        assert p["stream"] == truth_entry["stream"]
        assert _rel(p["delay"], truth_entry["delay"]) < 0.15, p
    elif name == "load_cell_scale":
        assert p["cable"] == truth_entry["cable"]
        assert _rel(p["scale"] - 1.0, truth_entry["scale"] - 1.0) < 0.15, p
    elif name == "cable_elasticity":
        assert _rel(p["stiffness"], truth_entry["stiffness"]) < 0.15, p
    elif name in ("cable_mass", "body_mass"):
        k = "mass" if name == "cable_mass" else "mass_error"
        assert _rel(p[k], truth_entry[k]) < 0.15, p
    else:   # every parameter (vector component) the recording determines: σ below 5 % of its size
        determined = 0
        for k, v in truth_entry.items():
            if k == "name":
                continue
            size = float(np.linalg.norm(np.atleast_1d(np.asarray(v, float))))
            est, std = np.atleast_1d(np.asarray(p[k], float)), np.atleast_1d(np.asarray(found["parameters_std"][k]))
            for i, (e, s, t) in enumerate(zip(est, std, np.atleast_1d(np.asarray(v, float)))):
                if s < 0.05 * size:
                    determined += 1
                    assert abs(e - t) < 0.15 * size, (k, i, p[k], v)
        assert determined, f"no parameter determined to 5 %: {found['parameters_std']}"


def check_inertia(res: dict, key: str = "inertia_about_cg_after", std_key: str = "inertia_std_after",
                  before: bool = True):
    """Every entry within the bounds the recording allows: 0.5 % (of the entry; of the largest
    diagonal for products) or 3 reported σ, whichever is larger (a 60 s recording of a random
    rig determines some entries only to ~1 %; the 120 s figures are bench/bench_diagnose.py's);
    and, where the concealed effect distorted an entry by more than 1 %, the diagnosis brought
    it at least halfway back."""
    tru = res["truth"]["inertia_about_cg"]
    big = max(tru["ixx"], tru["iyy"], tru["izz"])
    J, s, J0 = res[key], res[std_key], res["inertia_about_cg_before"]
    for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
        ref = abs(tru[k]) if k in ("ixx", "iyy", "izz") else big
        err, err0 = J[k] - tru[k], J0[k] - tru[k]
        assert abs(err) <= max(0.005 * ref, 3 * s[k]), \
            f"{k}: {J[k]:.2f} vs truth {tru[k]:.2f} ({100 * err / ref:+.3f} %, σ {s[k]:.2f})"
        if before and abs(err0) > 0.01 * ref:
            assert abs(err) < 0.5 * abs(err0), \
                f"{k}: error {100 * err0 / ref:+.2f} % before, {100 * err / ref:+.2f} % after"


@pytest.mark.parametrize("name", list(SUITE_CASES))
def test_concealed_effect_is_named_estimated_and_removed(results, name):
    res = results[name]
    eff, group = CASES[name]
    assert res["mismatch"], f"{name}: no mismatch found; candidates {res['candidates'][:3]}"
    first = res["effects"][0]
    assert first["name"] == name, f"modelled as {[e['name'] for e in res['effects']]}, concealed {name}"
    if not first.get("told_apart", True):   # named by its class only: the concealed effect among the candidates
        assert name in candidate_names(first), first["candidates"]
    check_parameters(name, first, res["truth"]["effects"][0], res["excitation"])
    before, after = res["residual_rms_before"], res["residual_rms_after"]
    red = max(1 - after[k] / before[k] for k in before if k.startswith(group))
    assert red >= 0.30, f"{group} residual RMS reduced by only {100 * red:.0f} %"
    check_inertia(res)


def candidate_names(entry: dict) -> set:
    """The effect names among an entry's candidates ("name", "name label", joined by " + ")."""
    return {part.split()[0] for c in entry["candidates"] for part in c.split(" + ")}


def test_only_what_the_recording_tells_apart_is_named(results):
    """On every recording of the fixture (each effect of the library concealed alone, a clean
    run), no absent effect is named: every plausible and determined effect
    told apart is the concealed one, and an effect not told apart stands for a class whose candidates hold the
    concealed one, with its rivals' likelihood ratios within the bar and what would tell them
    apart (:mod:`~rig_identification.diagnosis.distinguish`)."""
    for case, res in results.items():
        truth = {e["name"] for e in res["truth"].get("effects", [])}
        for e in res["effects"]:
            if not e.get("plausible", True):   # said to be no finding (implausible or not determined)
                continue
            if e.get("told_apart", True):
                assert e["name"] in truth, (case, e["name"])
                continue
            assert truth & candidate_names(e), (case, e["candidates"])
            lam, bar = e["evidence"]["rivals"]["likelihood_ratios"], e["evidence"]["rivals"]["bar"]
            assert len(lam) >= 2 and max(abs(x - lam[0]) for x in lam) < bar, (case, lam, bar)
            assert e["tells_apart"] and e["class"], e


def test_a_daq_clock_behind_the_imu_is_one_delay_of_both_force_streams(results):
    """The load cells and the exciter 15 ms late together: named as one ``sensor_delay`` of the
    stream ``load_cells+exciter`` (only the streams' relative time is in the recording), its
    delay within 15 %, the inertia back within the bounds."""
    res = results["daq_delay"]
    first = res["effects"][0]
    assert first["name"] == "sensor_delay" and first["parameters"]["stream"] == "load_cells+exciter", res["effects"]
    assert _rel(first["parameters"]["delay"], 0.015) < 0.15, first["parameters"]
    check_inertia(res)


NEW_CANDIDATES = {"gyro_bias_drift", "gyro_scale", "structural_mode"}


def test_new_candidates_are_not_named_where_the_recording_lacks_them(results):
    """The gyro's bias drift and scale and a sensor mount's structural mode (the library's
    newest, with many columns or fitted from outside the band) are named on none of the
    fixture's recordings: the clean one and each with another effect concealed."""
    for name, res in results.items():
        named = {e["name"] for e in res["effects"]}
        assert not named & NEW_CANDIDATES, (name, sorted(named))


def test_clean_simulation_has_no_mismatch(results):
    res = results["clean"]
    assert not res["mismatch"], [e["name"] for e in res["effects"]]
    assert res["inertia_about_cg_after"] == res["inertia_about_cg_before"]
    check_inertia(res)


def test_reference_clean_recording_has_no_mismatch():
    from rig_identification.diagnosis.selection import diagnose
    from rig_identification.io.recording import read_recording
    d = diagnose(read_recording(recording("visible_case16_clean")))
    assert not d.mismatch, [e["name"] for e in d.effects]


def _damped_cli():
    """Job of test_reference_damped_recording_names_the_damping: `rig-identify diagnose --model pem
    --json --report` on the damped reference recording.  Returns (exit status, stdout, stderr, the
    report folder's file names)."""
    import shutil
    import subprocess
    import sys
    import tempfile
    from pathlib import Path
    tmp = Path(tempfile.mkdtemp(prefix="test_diagnose_"))
    try:
        out = subprocess.run([sys.executable, "-m", "rig_identification.cli.main", "diagnose",
                              str(recording("visible_case16_damped")), "--model", "pem", "--json", "--report",
                              str(tmp / "report")],
                             capture_output=True, text=True, timeout=600)
        files = sorted(p.name for p in (tmp / "report").iterdir()) if (tmp / "report").is_dir() else []
        return out.returncode, out.stdout, out.stderr, files
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


background("damped_cli", __file__, _damped_cli, {"run": ()})


def test_reference_damped_recording_names_the_damping():
    """visible_case16_damped conceals viscous damping (its truth.yaml lists the coefficients):
    named first, both coefficients within 15 %, inertia back within the bounds; the CLI's
    JSON and report hold the same."""
    from rig_identification.io.recording import read_recording
    rec = read_recording(recording("visible_case16_damped"))
    tru = next(e for e in rec.truth["effects"] if e["name"] == "viscous_damping")
    code, stdout, stderr, files = gather("damped_cli")["run"]
    assert code == 0, stderr
    res = json.loads(stdout)
    res["truth"] = rec.truth
    first = res["effects"][0]
    assert first["name"] == "viscous_damping"
    # one forcing amplitude: viscous, quadratic and Coulomb damping explain it alike (measured: Λ
    # within the bar), so the diagnosis names the class, with the damping modelled as viscous
    if not first.get("told_apart", True):
        assert first["class"] == "velocity-dependent damping" and "viscous_damping" in first["candidates"], first
        assert "second forcing amplitude" in first["tells_apart"]
        lam = first["evidence"]["rivals"]["likelihood_ratios"]
        assert max(abs(x - lam[0]) for x in lam) < first["evidence"]["rivals"]["bar"], first["evidence"]
    for k in ("linear", "angular"):
        assert _rel(first["parameters"][k], tru[k]) < 0.15, (k, first["parameters"][k], tru[k])
    assert res["residual_rms_after"]["gyro_y"] < 0.5 * res["residual_rms_before"]["gyro_y"]
    check_inertia(res)
    # the inertia before the damping was added is far off: the mismatch mattered
    assert abs(res["inertia_about_cg_before"]["izz"] / tru_izz(rec) - 1) > 0.02
    assert {"diagnosis.json", "index.html", "residuals_gyro.png", "spectra_gyro.png"} <= set(files)


def tru_izz(rec) -> float:
    return rec.truth["inertia_about_cg"]["izz"]


def _default_rig_pipeline(name: str, effect: dict, refine: bool, cg_std: list | None = None) -> tuple:
    """Job: thesis case 16 (config/rigs/default.yaml), 60 s at the reference noise, with
    ``effect`` concealed (experiment ``name``): the rigid-body fit (``identify_recording``, ``refine``) and
    ``pipeline.with_diagnosis`` on it (what `rig-identify inertia` does under model error; with
    ``cg_std`` (3,) m, as `inertia --cg` does with a static test's CG of that σ).
    Returns (truth, the body's mass in rig.yaml, rigid-body result, result)."""
    from pathlib import Path

    from rig_identification.io.recording import Recording
    from rig_identification.model.simulator import experiment_from_dict, simulate
    from rig_identification.pipeline.offline import identify_recording, with_diagnosis
    d = yaml.safe_load((Path(__file__).resolve().parents[1] / DEFAULT).read_text())
    d["rig"].pop("dummy_mass", None)
    d["duration"] = DURATION
    d["effects"] = [effect]
    d["sensors"]["noise"] = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5,
                             "inclinometer": 0.0002}
    sim = simulate(experiment_from_dict(d, name))
    rec = Recording(sim.rig, sim.sensors, sim.truth)
    rigid = identify_recording(rec, refine=refine)
    cov = None if cg_std is None else np.diag(np.square(cg_std))
    return sim.truth, sim.rig.mass, rigid, with_diagnosis(rec, rigid, cg_covariance=cov)


background("delay_pipeline", __file__, _default_rig_pipeline,
           {"run": ("delayed load cells", {"name": "sensor_delay", "stream": "load_cells", "delay": 0.02}, True)})


def test_inertia_removes_a_diagnosed_sensor_delay_and_identifies_again():
    """`pipeline.with_diagnosis` (what `rig-identify inertia` does under model error) on thesis
    case 16, 60 s at the reference noise, the load cells 20 ms late: the rigid-body fit is off
    by several percent; diagnose names the delay, it is removed from the data and the
    recording identified again — within 0.5 % (products: of the largest diagonal) and 3 σ,
    with the propagated-noise σ, since the residual is the noise's again."""
    from rig_identification.pipeline.offline import compare_to_truth
    truth, _, rigid, res = gather("delay_pipeline")["run"]
    assert max(abs(c["error_percent"]) for c in compare_to_truth(rigid, truth).values()) > 5.0
    assert [e["name"] for e in res.diagnosis["effects"]] == ["sensor_delay"]
    assert res.diagnosis["handled"] == "removed from the data"
    assert res.uncertainty.startswith("propagated sensor noise") and np.max(res.residual_excess) < 2.0
    assert rigid.validation.verdict == "model_error" and res.validation.verdict == "ok", res.validation.summary
    for k, c in compare_to_truth(res, truth).items():
        assert abs(c["error_percent"]) < 0.5 and abs(c["error_sigma"]) < 3.0, (k, c)
    assert abs(res.rigid_body["inertia_about_cg"]["ixx"] / truth["inertia_about_cg"]["ixx"] - 1) > 0.05


def test_cable_mass_rig_and_tensor_invert_the_simulated_body():
    """`corrected` with a cable mass gives the heavier body the simulator moves (its half-cable
    point masses at the body anchors: mass and centre of gravity), and `body_inertia` takes
    their share off that body's tensor (parallel-axis theorem), back to the vehicle's own."""
    from rig_identification.diagnosis.selection import body_inertia, corrected
    from rig_identification.io.recording import Recording
    from rig_identification.io.rig import DummyMass
    from rig_identification.model.simulator import _with_dummy, experiment_from_dict, inertia_tensor, simulate
    d = random_experiment(7, [], duration=1.0)
    sim = simulate(experiment_from_dict(d, "random"))
    rig, mu = sim.rig, 1.7
    J = inertia_tensor(d["inertia_about_cg"])
    m, c, Jc = rig.mass, rig.require_cg(), J
    for b in rig.body_anchors:
        m, c, Jc = _with_dummy(m, c, Jc, DummyMass(mu, np.asarray(b, float)))
    rec = corrected(Recording(rig, sim.sensors, sim.truth, "x"), {("cable_mass", ""): mu})
    assert rec.rig.mass == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(rec.rig.center_of_gravity, c, atol=1e-12)
    assert np.abs(Jc - J).max() > 10.0       # the cables' share is not negligible
    np.testing.assert_allclose(body_inertia(Jc, rig, mu), J, atol=1e-9)


background("weight_pipeline", __file__, _default_rig_pipeline,
           {"run": ("cable mass", {"name": "cable_mass", "mass": 3.0}, False)})


def test_inertia_diagnoses_a_weight_surplus_the_residual_does_not_show():
    """Thesis case 16, 60 s at the reference noise, 3 kg cables whose lower halves hang on the
    body outside the load cells: the heavier body is still a rigid body, so the rigid-body fit
    is biased by more than 0.5 % without a misfit; the load cells carry ~0.4 % more than
    rig.yaml's weight, which `pipeline.with_diagnosis` (what `rig-identify inertia` does)
    takes as model error: diagnose names the cables' mass within 15 %, and the body's own
    tensor comes back within 0.5 % (products: of the largest diagonal) and 3 σ."""
    from rig_identification.pipeline.fit_validation import WEIGHT_TOLERANCE
    from rig_identification.pipeline.offline import compare_to_truth
    truth, mass, rigid, res = gather("weight_pipeline")["run"]
    assert max(abs(c["error_percent"]) for c in compare_to_truth(rigid, truth).values()) > 0.5
    assert rigid.weight_surplus == pytest.approx(4 * 1.5 / mass, rel=0.1)
    assert rigid.weight_surplus > WEIGHT_TOLERANCE
    first = res.diagnosis["effects"][0]
    assert first["name"] == "cable_mass" and _rel(first["parameters"]["mass"], 3.0) < 0.15, first
    for k, c in compare_to_truth(res, truth).items():
        assert abs(c["error_percent"]) < 0.5 and abs(c["error_sigma"]) < 3.0, (k, c)


background("cg_pipeline", __file__, _default_rig_pipeline,
           {"run": ("CG off", {"name": "cg_offset", "offset": [0.0, 0.0, 0.03]}, False, [0.002, 0.002, 0.02])})


def test_inertia_with_a_static_tests_cg_corrects_its_height():
    """`inertia --cg` with a static test whose CG is 30 mm low (σ 20 mm in height, as a light
    dummy gives): thesis case 16, 60 s. The rigid-body fit about that CG is `model_error` with
    Iyy off by more than 1 %; the diagnosis, which then screens the CG as a data error within
    its σ, names the offset (within 2 mm), fits about the corrected CG and validates: every
    entry within 0.5 % and 3 σ, the CG the truth's within 2 mm."""
    from rig_identification.pipeline.offline import compare_to_truth
    truth, _, rigid, res = gather("cg_pipeline")["run"]
    assert rigid.validation.verdict == "model_error"
    assert max(abs(c["error_percent"]) for c in compare_to_truth(rigid, truth).values()) > 1.0
    (e,) = res.diagnosis["effects"]
    assert e["name"] == "cg_offset" and np.abs(np.array(e["parameters"]["offset"]) - [0, 0, 0.03]).max() < 0.002, e
    assert res.validation.verdict == "ok", res.validation.summary
    for k, c in compare_to_truth(res, truth).items():
        assert abs(c["error_percent"]) < 0.5 and abs(c["error_sigma"]) < 3.0, (k, c)
    assert np.abs(res.center_of_gravity - np.asarray(truth["center_of_gravity"])).max() < 0.002


def test_a_cg_offset_beyond_the_static_tests_sigma_is_not_plausible():
    """The CG the diagnosis may move is the static test's within 3 σ (χ²₃ 99.73 %): 30 mm in
    height is plausible at σ 20 mm, not at σ 5 mm; without a static σ only the general range."""
    from rig_identification.diagnosis.plausible import implausible
    from rig_identification.io.rig import rig_from_dict
    rig = rig_from_dict(yaml.safe_load(open(DEFAULT))["rig"], "default")
    e = {"name": "cg_offset", "parameters": {"offset": [0.0, 0.0, 0.03]}}
    assert implausible(e, rig, cg_covariance=np.diag(np.square([0.002, 0.002, 0.02]))) is None
    why = implausible(e, rig, cg_covariance=np.diag(np.square([0.002, 0.002, 0.005])))
    assert why is not None and "beyond 3 σ of the static test's CG" in why
    assert implausible(e, rig) is None


def test_synchronous_rms_keeps_what_is_locked_to_the_forcing():
    """A residual = a waveform locked to the exciter's phase (fundamental and 2nd harmonic)
    + a free oscillation at an incommensurate frequency + white noise 3× the waveform:
    the synchronous RMS is the waveform's, within the noise left after averaging; the plain
    RMS is the noise's."""
    from rig_identification.diagnosis.selection import synchronous_rms
    rng = np.random.default_rng(5)
    fs, f_exc, T = 200.0, 0.91, 120.0
    t = np.arange(0.0, T, 1 / fs)
    phase = 2 * np.pi * f_exc * t + 0.3
    locked = 1.0 * np.cos(phase) + 0.5 * np.sin(2 * phase + 1.0)        # RMS √((1 + 0.25)/2)
    free = 2.0 * np.sin(2 * np.pi * 0.6180339 * t)
    noise = rng.normal(0.0, 3.0, t.size)
    out = synchronous_rms({"x": locked + free + noise, "free": free}, phase)
    true = math.sqrt((1.0 + 0.25) / 2)
    revs = f_exc * T
    # the noise left: σ/√(samples per bin) in each of 36 bins
    floor = 3.0 / math.sqrt(t.size / 36)
    assert abs(out["x"] - math.sqrt(true ** 2 + floor ** 2)) < 3 * floor, (out, true, floor, revs)
    assert out["free"] < 0.1 * 2.0 / math.sqrt(2)
    assert float(np.sqrt(np.mean((locked + free + noise) ** 2))) > 3 * out["x"]


def test_exciter_phase_needs_a_rotating_exciter():
    from rig_identification.diagnosis.selection import exciter_phase
    t = np.arange(0.0, 30.0, 0.005)
    exc_rot = np.eye(3)
    rot = 200.0 * np.column_stack([np.cos(2 * np.pi * t), np.sin(2 * np.pi * t), 0 * t])

    class W:
        pass
    w = W()
    w.exc_rot, w.f_exc = exc_rot, rot
    ph = exciter_phase(w)
    assert ph is not None and abs((ph[-1] - ph[0]) / (2 * np.pi) - 30.0) < 0.01
    w.f_exc = np.zeros_like(rot)             # no exciter
    assert exciter_phase(w) is None
    w.f_exc = rot * (t < 5.0)[:, None]       # stopped after 5 revolutions: too few
    assert exciter_phase(w) is None
