"""Know before you shake: the experiment design (rig-identify plan) and the rig model's information it ranks runs by."""
import json

import numpy as np
import pytest
from conftest import REPO, background, gather, run_cli
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation

from rig_identification.design.information import body_prior, combined, nominal_parameters, tensor_std
from rig_identification.design.planning import SPIN_AXES, resonances
from rig_identification.design.run import Run, load_plan_input, make_body
from rig_identification.design.screen import RigScreen
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import REFERENCE_NOISE, load_experiment
from rig_identification.model.linear_rig import rest_pose
from rig_identification.model.modes import natural_modes
from rig_identification.model.rig_ode import drive, rest_state
from rig_identification.model.rig_ode import simulate as run_model
from rig_identification.model.simulator import simulate

DEFAULT = REPO / "config" / "rigs" / "default.yaml"   # thesis case 16, reference sensors


def test_parametric_resonances_are_avoided():
    """On the thesis rig (case 16) an exciter at 2.02 Hz = f_roll + f_pitch pumps both swings
    until a cable goes slack; the design keeps 10 % away from modes, doubles and sums."""
    exp = load_experiment(DEFAULT)
    f = np.array([m.frequency for m in natural_modes(exp.rig, exp.mass, exp.cg, exp.inertia, 5e6)])
    avoid = resonances(f)
    assert np.min(np.abs(2.02 / avoid - 1)) < 0.01          # the sum roll + pitch
    assert np.min(np.abs(1.05 / avoid - 1)) > 0.1           # the thesis's 1.05 Hz is clear
    assert np.any(np.isclose(avoid, 2 * f[0])) and np.any(np.isclose(avoid, f[0] + f[2]))


def _thesis_body():
    rig, _, k = load_plan_input(str(DEFAULT))
    return make_body(rig, None, [2894.0, 0.0, 0.0, 695.0, -102.0, 3101.0], k)     # KEYS order


def test_the_screen_reads_the_rig_as_the_exact_model_does():
    """The design's screen is the rig model linearised about its rest pose: for a 2 N run of the
    thesis rig (0.02° of swing) its readings — each load cell, the gyro, the accelerometer, the
    inclinometer — are the exact model's (the rig model's integrator, from rest through the spin-up)
    within 2 % RMS in the fit's band (the vertical acceleration, whose first-order share is small,
    within 10 %), and its peak rotation and lowest tension are a simulation's.  (At 20 N the exact
    model's second-order terms already move the tensions by 4–13 % and the vertical acceleration by
    half: what the screen cannot see, and why the planner decides on the exact model's bound.)
    Its information grows as the force squared where the data outweigh the nuisance's priors, and
    two runs fitted at once determine every entry better than either alone."""
    body = _thesis_body()
    f, pos, axis, amp = 1.05, (0.8, -1.25, 1.29), "y-z", 2.0
    screen = RigScreen(body, 20.0, 5.0, rate=200.0)
    at = screen.at(f)
    lin = at.readings(pos, SPIN_AXES[axis], amp)
    p = nominal_parameters(body.rig, body.inertia, body.stiffness, body.mass).replace(
        exciter_position=np.array(pos), exciter_rotation=Rotation.from_euler("xyz", SPIN_AXES[axis]).as_matrix())
    t = screen.t
    ramp = np.clip(t / 2.0, 0.0, 1.0) ** 2                            # the simulator's spin-up over 2 s
    theta = np.where(t < 2.0, np.pi * f * t ** 2 / 2.0, 2 * np.pi * f * (t - 1.0))
    force = amp * np.column_stack([ramp * np.cos(theta), ramp * np.sin(theta)])
    exact, _ = run_model(p, rest_state(p, rest_pose(p)), drive(force, 1 / 200, 4))
    exact = exact - exact[0]
    sos = butter(4, 4 * f, fs=200.0, output="sos")
    window = t >= 5.0
    a, b = (sosfiltfilt(sos, v, axis=0)[window] for v in (lin, exact))
    assert a.shape == b.shape == (window.sum(), 4 + 3 + 3 + 2)
    rel = np.std(a - b, axis=0) / np.std(b, axis=0)
    vertical = 4 + 3 + 2                                                  # accel_z
    assert np.all(np.delete(rel, vertical) < 0.02) and rel[vertical] < 0.1, np.round(rel, 3)
    sim = simulate(body.experiment(Run(f, amp, pos, axis, duration=20.0)))
    c = at.candidate(pos, SPIN_AXES[axis], {"max_force_n": 1e4, "max_rotation_deg": 3.0, "min_tension_ratio": 0.2},
                     amplitude=amp)
    rot = sim.states.rotation
    assert c.rotation_deg == pytest.approx(np.degrees(np.max(np.linalg.norm((rot * rot[0].inv()).as_rotvec(), axis=1))),
                                           rel=0.03)
    T = sim.states.tensions
    assert 1 - c.min_tension_ratio == pytest.approx(1 - np.min(T / T[0]), rel=0.05)
    prior = body_prior(body.rig)
    strong = at.candidate(pos, SPIN_AXES[axis], {"max_force_n": 1e4, "max_rotation_deg": 3.0, "min_tension_ratio": 0.2},
                          amplitude=10 * amp)
    assert np.all(tensor_std([strong.information], prior) < 0.5 * tensor_std([c.information], prior))
    other = at.candidate((-0.8, 1.25, -0.46), SPIN_AXES["x"], {"max_force_n": 1e4, "max_rotation_deg": 3.0,
                                                                "min_tension_ratio": 0.2}, amplitude=amp)
    both = np.sqrt(np.diag(combined([c.information, other.information], prior))[:6])
    assert np.all(both < tensor_std([c.information], prior)) and np.all(both < tensor_std([other.information], prior))


def _plan_cli():
    """Job of test_plan_cli_json_keeps_cables_taut_and_beats_the_thesis_excitation: `rig-identify
    plan` (in the worker's process).  Returns (exit status, stdout, stderr)."""
    return run_cli("plan", DEFAULT, "--inertia", "2894", "695", "3101", "0", "0", "-102", "--json", "--quiet",
                   "--duration", "30", "--runs", "1", "--refine", "1", "--frequencies", "1.3", "1.6",
                   "--position", "0.8", "1.25", "1.29", "--position", "0.8", "-1.25", "1.29", "--max-force", "1000")


background("plan_cli", __file__, _plan_cli, {"run": ()})


def test_plan_cli_json_keeps_cables_taut_and_beats_the_thesis_excitation():
    """rig-identify plan on the config rig (short runs, a narrowed search to keep it quick), its
    force limit raised by --max-force 1000 over rig.yaml's 200 N: modes, runs, predictions,
    identifiability; the recommended run keeps every cable above 20 % of its static tension and
    the rotation below 3° in simulation, and every entry's predicted σ is smaller than with the
    thesis's 200 N at 1.05 Hz."""
    code, stdout, stderr = gather("plan_cli")["run"]
    assert code == 0, stderr
    d = json.loads(stdout)
    assert {"modes", "runs", "prediction", "baseline", "improvement", "limits"} <= set(d)
    assert d["limits"]["max_force_n"] == 1000.0 and d["runs"][0]["run"]["amplitude_n"] > 200.0
    assert [round(m["frequency_hz"], 2) for m in d["modes"][:3]] == [0.85, 1.18, 2.78]
    run = d["runs"][0]
    assert 1.3 <= run["run"]["frequency_hz"] <= 1.6 and run["run"]["spin_axis_body"] in SPIN_AXES
    assert run["min_tension_ratio"] >= 0.2 and run["peak_rotation_deg"] <= 3.0
    assert d["baseline"]["run"]["frequency_hz"] == 1.05 and d["baseline"]["run"]["amplitude_n"] == 200.0
    assert min(d["improvement"].values()) > 1.2
    # the weakest direction in the CLI's and the report's words (directions.describe_direction): the
    # thesis's excitation (a vertical spin axis at a base corner) leaves Izz the least determined
    base = d["baseline"]["prediction"]
    weak = base["weakly_determined"][0]
    assert weak["weakest"] and weak["mostly"] == "izz"
    assert weak["text"].startswith("The most weakly determined combination is ")
    # one run: the plan's σ is that run's, the rig model's bound along its simulation; the improvement
    # is the baseline's σ over it
    std, bstd = d["prediction"]["std"], base["std"]
    assert set(std) == set(KEYS) and std == pytest.approx(run["prediction"]["std"], rel=1e-9)
    assert all(0 < std[k] < bstd[k] for k in KEYS), (std, bstd)
    assert d["improvement"] == pytest.approx({k: bstd[k] / std[k] for k in KEYS})
    # both against the default target, ±1 % at 95 % of each entry's scale; the plan's half-widths
    # are 1.96 times its predicted σ over that scale, and a run of length_factor × 30 s reaches it
    pb, pp = d["precision"]["baseline"], d["precision"]["plan"]
    theta = np.array([2894.0, 0.0, 0.0, 695.0, -102.0, 3101.0])   # KEYS order
    scale = np.where([True, False, False, True, False, True], theta, 3101.0)
    for p, sd in ((pb, bstd), (pp, std)):
        hw = np.array([p["half_width"][k] for k in KEYS])
        np.testing.assert_allclose(hw, 1.959963984540054 * np.array([sd[k] for k in KEYS]) / scale, rtol=1e-9)
        assert p["short"] == [k for k, h in zip(KEYS, hw) if h > 0.01]
        if p["short"]:
            assert p["length_factor"] == pytest.approx((hw.max() / 0.01) ** 2) and "each run's 30 s" in p["text"]


LIMIT = 150.0   # N: the exciter's max_force of test_a_rig_yaml_max_force_bounds_every_recommended_force


def _plan_with_max_force(max_force):
    """Job of test_a_rig_yaml_max_force_bounds_every_recommended_force: `rig-identify plan --json`
    (the planner's smallest search: 20 s runs, one run, one candidate simulated, 1.3–1.6 Hz, the
    top corner) on the config rig with rig.yaml's ``exciter.max_force`` set to ``max_force`` N, or
    without it (None).  Returns (exit status, stdout, stderr)."""
    import tempfile

    import yaml
    d = yaml.safe_load(DEFAULT.read_text())
    d["rig"]["exciter"].pop("max_force", None)
    if max_force is not None:
        d["rig"]["exciter"]["max_force"] = max_force
    with tempfile.TemporaryDirectory(prefix="test_planning_") as tmp:
        path = f"{tmp}/rig.yaml"
        with open(path, "w") as f:
            yaml.safe_dump(d, f)
        return run_cli("plan", path, "--inertia", "2894", "695", "3101", "0", "0", "-102", "--json",
                       "--duration", "20", "--runs", "1", "--refine", "1", "--frequencies", "1.3", "1.6",
                       "--position", "0.8", "1.25", "1.29")


background("plan_max_force", __file__, _plan_with_max_force, {"limited": (LIMIT,), "free": (None,)})


def test_a_rig_yaml_max_force_bounds_every_recommended_force():
    """rig.yaml ``exciter.max_force: 150`` → every force amplitude plan recommends is ≤ 150 N and
    the limits say 150 N; the same rig without it asks more than 150 N (the rotation and tension
    limits alone allow it) and says on stderr that the force is not limited because rig.yaml gives
    no max_force.  Each screening line on stderr counts the frequencies screened."""
    out = gather("plan_max_force")
    (code, stdout, err), (code_free, stdout_free, err_free) = out["limited"], out["free"]
    assert code == 0, err
    assert code_free == 0, err_free
    limited, free = json.loads(stdout), json.loads(stdout_free)
    assert limited["limits"]["max_force_n"] == LIMIT and free["limits"]["max_force_n"] == float("inf")
    assert limited["runs"] and all(r["run"]["amplitude_n"] <= LIMIT for r in limited["runs"]), limited["runs"]
    assert max(r["run"]["amplitude_n"] for r in free["runs"]) > LIMIT, free["runs"]
    assert "warning: the exciter's force is not limited: rig.yaml gives no exciter.max_force" in err_free
    assert "not limited" not in err
    screening = [ln for ln in err.splitlines() if ln.startswith("rig-identify: screening ")]
    assert screening and all(" of " in ln and ln.endswith(" s") for ln in screening), err


@pytest.mark.parametrize("args, words", [
    (["--inertia", "2894", "695", "3101", "0", "0", "-102", "--runs", "1", "--vary-geometry", "1"], "--runs 2"),
    (["--inertia", "2894", "695", "3101", "0", "0", "-102", "--geometry", "no_such_rig.yaml"], "no_such_rig.yaml"),
    (["--inertia", "100", "100", "300", "0", "0", "0"], "physically consistent"),
    (["--inertia", "2894", "695", "3101", "0", "0", "-102", "--mass", "-5"], "--mass"),
])
def test_plan_cli_user_errors(args, words):
    code, _, err = run_cli("plan", DEFAULT, *args)
    assert code == 2
    assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def _default_body():
    from rig_identification.design.planning import Body
    from rig_identification.model.experiment import REFERENCE_RATES
    exp = load_experiment(DEFAULT)
    return Body(exp.rig, exp.mass, exp.inertia, np.full(len(exp.rig.cables), 5e6), dict(REFERENCE_RATES),
                dict(REFERENCE_NOISE))


def test_geometry_variants_hang_the_body_near_where_the_rig_does():
    """Each cable-geometry variant moves the ceiling anchors 1 m along one world axis and
    re-sets the lengths to the rig's equilibrium pose: the body settles near it (within
    5 cm and 3°: the new cable directions balance the weight at a nearby pose), every cable
    taut, and the modes change."""
    from rig_identification.design.planning import geometry_variants
    from rig_identification.model.cables import CableModel
    from rig_identification.model.equilibrium import equilibrium
    body = _default_body()
    rig = body.rig
    cg = rig.require_cg()
    p0, R0, T0 = equilibrium(rig, body.mass, cg, CableModel.spring(rig, body.mass, stiffness=body.stiffness))
    f0 = [m.frequency for m in natural_modes(rig, body.mass, cg, body.inertia, body.stiffness)]
    variants = geometry_variants(body, 1.0)
    assert len(variants) >= 2
    for label, vr in variants:
        moved = np.abs(vr.ceiling_anchors - rig.ceiling_anchors)
        ax = 0 if "world x" in label else 1
        assert np.allclose(moved[:, ax], 1.0) and np.allclose(np.delete(moved, ax, axis=1), 0.0), label
        p, R, T = equilibrium(vr, body.mass, cg, CableModel.spring(vr, body.mass, stiffness=body.stiffness))
        assert np.linalg.norm(p - p0) < 0.05, (label, p - p0)
        assert np.degrees(np.linalg.norm((R * R0.inv()).as_rotvec())) < 3.0, label
        assert np.all(T > 0.1 * body.mass * rig.gravity / len(T)), (label, T)
        f = [m.frequency for m in natural_modes(vr, body.mass, cg, body.inertia, body.stiffness)]
        assert max(abs(a / b - 1) for a, b in zip(f[:3], f0[:3])) > 0.02, (label, f, f0)


def _limits_in_simulation(body, run) -> tuple[float, float]:
    """Lowest tension ratio and peak rotation (deg) of ``run`` simulated on ``body``."""
    sim = simulate(body.experiment(run))
    T = sim.states.tensions
    rot = sim.states.rotation
    return (float(np.min(T / T[0][None, :])),
            float(np.degrees(np.max(np.linalg.norm((rot * rot[0].inv()).as_rotvec(), axis=1)))))


def _second_geometry_plan():
    """Job of test_second_run_on_another_cable_geometry_stays_within_the_limits: the plan, and
    its other geometry's best second run simulated again on that geometry and on the rig's
    own cables.  Returns (body, label, variant rig, plan, (limits there, limits on the rig))."""
    from rig_identification.design.planning import PlanOptions, geometry_variants, plan_experiment
    body = _default_body()
    rig = body.rig
    label, vr = next((lab, r) for lab, r in geometry_variants(body, 1.0) if "farther apart along world y" in lab)
    base = Run(1.05, 200.0, tuple(rig.exciter.position), "z", 20.0, 2.0, tuple(rig.exciter.rpy))
    opts = PlanOptions(duration=20.0, refine=1, frequencies=(1.3, 1.6),
                       positions=((0.8, 1.25, 1.29), (0.8, -1.25, -0.46)), geometries=((label, vr),))
    plan = plan_experiment(body, base, opts)
    limits = None
    if len(plan.other_geometries) == 1:
        c = plan.other_geometries[0]
        limits = (_limits_in_simulation(c.body, c.run), _limits_in_simulation(body, c.run))
    return body, label, vr, plan, limits


background("second_geometry", __file__, _second_geometry_plan, {"run": ()}, first=True)


def test_second_run_on_another_cable_geometry_stays_within_the_limits():
    """plan_experiment with one other cable geometry (ceiling anchors 1 m farther apart in
    y; a narrowed search, 20 s runs) searches it for the second run: its best second run
    there, simulated again on that geometry by the package's simulator (DOP853; the plan's runs
    are the rig model's fixed-step integrator), keeps every cable above 20 % of its static
    tension and the rotation below 3° as the plan says (on the rig's own cables it would
    not behave the same); the plan is chosen between it and the best run done twice, and
    no pair it could make of the runs it reports (each of its runs twice, its two runs, a
    run of it with the other geometry's) does better."""
    body, label, vr, plan, limits = gather("second_geometry")["run"]
    assert len(plan.other_geometries) == 1
    c = plan.other_geometries[0]
    assert c.geometry == label and c.body.rig.cables is vr.cables
    (tmin, peak), on_rig = limits
    assert tmin == pytest.approx(c.min_tension_ratio, abs=1e-4) and peak == pytest.approx(c.peak_rotation_deg, abs=1e-4)
    assert tmin >= 0.2 * 0.999 and peak <= 3.0 * 1.001
    assert on_rig != pytest.approx((tmin, peak), rel=0.02)   # the geometry matters
    d = c.to_dict(plan.prior, plan.inertia)["cable_geometry"]
    assert d["label"] == label and [x["length"] for x in d["cables"]] == list(vr.cable_lengths)
    ref = plan.baseline_std

    def worst(*runs):
        return float(np.max(tensor_std([r.information for r in runs], plan.prior) / ref))
    first = plan.runs[0]
    assert worst(*plan.runs) == pytest.approx(min(worst(first, first), worst(first, c)), rel=1e-9)
    assert worst(*plan.runs) == pytest.approx(float(np.max(plan.std / ref)), rel=1e-9)
    pairs = [(a, a) for a in plan.runs] + [(plan.runs[0], plan.runs[-1])] + [(a, c) for a in plan.runs]
    assert worst(*plan.runs) <= min(worst(*p) for p in pairs) * (1 + 1e-9)


def test_spin_axes_point_where_their_names_say():
    """Each candidate spin axis (SPIN_AXES: body x, y, z and the diagonals between two of
    them) is the z axis of its exciter rpy, and the plan's JSON gives that unit vector."""
    from scipy.spatial.transform import Rotation

    assert len(SPIN_AXES) == 9
    for name, rpy in SPIN_AXES.items():
        v = np.zeros(3)
        for sign, axis in zip(("+",) + tuple(name[1:-1]), name[::2]):
            v["xyz".index(axis)] = 1.0 if sign == "+" else -1.0
        v /= np.linalg.norm(v)
        z = Rotation.from_euler("xyz", rpy).apply([0.0, 0.0, 1.0])
        assert z == pytest.approx(v, abs=1e-12), name
        assert Run(1.5, 500.0, (0.0, 0.0, 0.0), name).to_dict()["spin_axis_unit_body"] == pytest.approx(v, abs=1e-6)


def test_the_force_amplitude_stays_within_the_exciters_limit():
    """The planner's largest force within the limits (amplitude_at_limits, as plan brings every
    candidate run to it): on the config rig the thesis's run at 1.05 Hz may go well beyond 200 N
    by the rotation and tension limits alone; with the exciter's max_force 150 N it is 150 N, with
    its rotation and tensions within the limits.  plan takes rig.yaml's exciter.max_force unless
    --max-force says otherwise (test_rig.py)."""
    from rig_identification.design.planning import amplitude_at_limits
    body = _thesis_body()
    rig = body.rig
    run = Run(1.05, 200.0, tuple(rig.exciter.position), "z", 20.0, 2.0, rpy=(0.0, 0.0, 0.0))
    free = amplitude_at_limits(body, run)
    limited = amplitude_at_limits(body, run, max_force=150.0)
    assert free is not None and limited is not None
    assert free.run.amplitude > 200.0, free.run.amplitude
    assert limited.run.amplitude == pytest.approx(150.0, rel=0.03) and limited.run.amplitude <= 150.0
    assert limited.peak_rotation_deg <= 3.0 and limited.min_tension_ratio >= 0.2
