"""The static CG fit on rigs of 3, 5 and 6 cables (random rigs of scenarios.random_experiment,
'wide' layout, simulated static baseline and dummy with the package's simulator, reference
noise, 10 s each, cable stiffness 5e6 N/m that rig.yaml does not state).

Each: the CG within 3 σ of the truth, both with the geometry as surveyed (the default σ) and
with the geometry exact (the noise-only σ, which this simulated rig.yaml deserves); the
validation passes.
"""
import numpy as np
import pytest

from rig_identification.design.scenarios import random_experiment
from rig_identification.model.experiment import experiment_from_dict
from rig_identification.model.simulator import simulate
from rig_identification.statics import CgOptions, StaticState, estimate_cg


def static_pair(seed: int, cables: int, layout: str = "wide"):
    """(rig, baseline StaticState, dummy StaticState, true CG): a 50 kg dummy 0.3 m below the
    first body anchor (a corner of the carrying frame's top); ``layout`` as
    scenarios.random_experiment's."""
    d = random_experiment(seed, cables, layout, duration=10.0)
    b = np.array([c["body_anchor"] for c in d["rig"]["cables"]])
    d["rig"]["dummy_mass"] = {"mass": 50.0, "position": (b[0] + [0.0, 0.0, -0.3]).tolist()}
    states = []
    for kind in ("baseline", "dummy"):
        d["static"] = {"kind": kind, "duration": 10.0}
        sim = simulate(experiment_from_dict(d, d["name"]))
        states.append(StaticState.from_window(sim.sensors, label=kind))
    return sim.rig, states[0], states[1], np.array(d["rig"]["body"]["center_of_gravity"], float)


@pytest.mark.parametrize("cables, seed", [(3, 1), (5, 2), (6, 2)], ids=["3_cables", "5_cables", "6_cables"])
def test_cg_within_3_sigma(cables, seed):
    rig, b, d, truth = static_pair(seed, cables)
    assert len(rig.cables) == cables and rig.center_of_gravity is None
    for opts in (CgOptions(), CgOptions.exact_geometry()):
        res = estimate_cg(rig, b, d, opts)
        err = res.center_of_gravity - truth
        assert np.all(np.abs(err) <= 3 * res.center_of_gravity_std), (cables, err / res.center_of_gravity_std)
        assert res.validation.verdict == "ok", res.validation.failed
        assert not res.warnings, res.warnings
    # noise alone: the horizontal CG to a few hundredths of a mm, the height to ~1 mm
    assert np.all(res.center_of_gravity_std[:2] < 1e-4) and res.center_of_gravity_std[2] < 1.5e-3
    assert res.weakly_determined["axis"] == "z"
    # the fitted cable stiffness is the simulator's
    assert abs(res.cable_stiffness - 5e6) < 3 * res.cable_stiffness_std + 1e4
