"""The static CG fit on rigs of 3, 5 and 6 cables (random rigs of scenarios.random_experiment,
'wide' layout, simulated static baseline and dummy with the package's simulator, reference
noise, 10 s each, cable stiffness 5e6 N/m that rig.yaml does not state).

Each: the CG within 3 σ of the truth, both with the geometry as surveyed (the default σ) and
with the geometry exact (the noise-only σ, which this simulated rig.yaml deserves); the
validation passes.
"""
import numpy as np
import pytest
from synthetic import static_pair

from rig_identification.statics import CgOptions, estimate_cg


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
