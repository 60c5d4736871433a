"""Any legitimate rig: 3 or 5 cables, the exciter at a corner — planned, its CG found (the rig
model's fits of such rigs: test_rig_model.py).

Random NHTSA vehicles in carrying frames (the body frame off the CG), cables splayed so that
their lines cross near the CG (rig_identification.design.scenarios, layout "wide"), reference noise,
45 s at 200 Hz.  The sweep over many rigs is bench/bench_any_rig.py (and bench_trust.py).
"""

import sys
from dataclasses import replace

import numpy as np
import pytest
from conftest import REPO, background, gather
from synthetic import static_pair

from rig_identification.design.information import tensor_bound
from rig_identification.design.planning import PlanOptions, Run, make_body, plan_experiment
from rig_identification.design.scenarios import CABLE_STIFFNESS, simulate_random
from rig_identification.estimation.rig_record import record
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import REFERENCE_NOISE
from rig_identification.statics import estimate_cg


def _plan(cables: int, seed: int, frequencies: tuple):
    """Job: `rig-identify plan`'s search (design.planning) on a random 'wide' rig, narrowed: 30 s
    runs, the rig's exciter position, the frequency range (low, high) Hz, one run."""
    d, sim = simulate_random(seed, cables, "wide", [], 10.0)
    tru = sim.truth["inertia_about_cg"]
    body = make_body(sim.rig, None, [tru[k] for k in KEYS], stiffness=CABLE_STIFFNESS)
    ex = d["excitation"]["rotating"]
    rig = sim.rig
    base = Run(ex["frequency"], ex["amplitude"], tuple(rig.exciter.position), "z", 30.0, 2.0, tuple(rig.exciter.rpy))
    return plan_experiment(body, base, PlanOptions(duration=30.0, refine=1, max_runs=1, frequencies=frequencies,
                                                   positions=(tuple(rig.exciter.position),)))


background("any_rig_plan", __file__, _plan, {"3": (3, 7102, (0.8, 1.6)), "5": (5, 7206, (0.8, 1.6))})


def test_plan_on_a_three_cable_rig_keeps_the_cables_taut():
    """`rig-identify plan`'s search on a 3-cable rig (a narrowed search, 30 s runs): the plan
    predicts σ for every entry, its run keeps every cable above 20 % of its static tension
    and the rotation below 3°, and it is no worse than the baseline on the least-improved
    entry."""
    plan = gather("any_rig_plan", "3")["3"]
    run = plan.runs[0]
    assert np.all(np.isfinite(plan.std)) and np.all(plan.std > 0)
    assert run.min_tension_ratio >= 0.2 * 0.999 and run.peak_rotation_deg <= 3.0 * 1.001
    assert np.max(plan.std / plan.baseline_std) <= 1.0 + 1e-9, plan.std / plan.baseline_std


@pytest.mark.parametrize("cables,seed,layout", [(3, 7101, "wide"), (5, 7206, "wide"), (3, 21022, "random"),
                                                (5, 21011, "random")])
def test_static_cg_on_the_same_rigs(cables, seed, layout):
    """The static CG fit (``statics.estimate_cg``, the geometry as surveyed) on the rigs the
    inertia is identified on above, and on two of bench_any_rig's "random" rigs (each cable
    its own splay, the ceiling anchors at heights within ±0.3 m, the body hanging a little
    tilted): a 50 kg dummy 0.3 m below the first body anchor, 10 s baseline and dummy with
    reference noise; the CG within 3 σ of the truth and the validation ok."""
    rig, baseline, dummy, truth = static_pair(seed, cables, layout)
    res = estimate_cg(rig, baseline, dummy)
    err = res.center_of_gravity - truth
    assert len(rig.cables) == cables
    assert np.all(np.abs(err) <= 3 * res.center_of_gravity_std), err / res.center_of_gravity_std
    assert res.validation.verdict == "ok", res.validation.failed


def test_plan_on_the_five_cable_rig_keeps_the_cables_taut():
    """`rig-identify plan`'s search on the 5-cable rig identified above (seed 7206; 30 s runs,
    the rig's exciter position, 0.8–1.6 Hz): σ predicted for every
    entry, the run within the limits (every cable above 20 % of its static tension, the
    rotation below 3°).  Not asserted: that it beats the baseline — the screen only shortlists
    (the linearised rig's ranking and the exact bound's differ, docs/rig_model.md)."""
    plan = gather("any_rig_plan", "5")["5"]
    run = plan.runs[0]
    assert np.all(np.isfinite(plan.std)) and np.all(plan.std > 0)
    assert run.min_tension_ratio >= 0.2 * 0.999 and run.peak_rotation_deg <= 3.0 * 1.001


def test_the_benches_bound_is_the_packages():
    """bench_any_rig, bench_trust and bench_crb judge every rig by bench_crb.bound: on a quiet
    4-cable rig (20 s) it is the package's own Cramér–Rao bound of the run at the reference noise
    (design.information.tensor_bound, what ``plan`` predicts), every entry finite and positive."""
    sys.path.insert(0, str(REPO / "bench"))
    import bench_crb
    _, quiet = simulate_random(7311, 4, "wide", [], 20.0, noise=bench_crb.QUIET)
    rc = record(quiet.sensors, quiet.rig)
    crb = bench_crb.bound(replace(rc, sigma=bench_crb.channel_noise(rc.channels)), quiet.rig, quiet.truth)
    assert np.all(np.isfinite(crb)) and np.all(crb > 0), crb
    np.testing.assert_allclose(crb, tensor_bound(quiet, REFERENCE_NOISE), rtol=1e-9)
