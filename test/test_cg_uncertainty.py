"""CG uncertainty with the rig's geometry as surveyed (rig-identify cg's default).

The reported σ (``center_of_gravity_std``) must cover the truth when rig.yaml's geometry is
off by the stated survey uncertainty (1 mm on every anchor coordinate, cable length and
dummy-position coordinate); the noise-only σ (``center_of_gravity_std_noise``) must be what
the fit reported before (the geometry taken as exact) -- and far too small for such a rig.yaml.
The recordings: the shipped simulated static pair (independent simulator, realistic noise),
whose rig.yaml is the simulator's exact geometry.
"""
from dataclasses import replace

import numpy as np
import pytest
from conftest import recording

from rig_identification.io.recording import read_recording
from rig_identification.io.rig import DummyMass
from rig_identification.statics import (
    DEFAULT_ANCHOR_STD,
    DEFAULT_DUMMY_POSITION_STD,
    DEFAULT_LENGTH_STD,
    CgOptions,
    StaticState,
    estimate_cg,
)

DRAWS = 30


@pytest.fixture(scope="module")
def pair():
    b = read_recording(recording("visible_case16_static/static_baseline"))
    d = read_recording(recording("visible_case16_static/static_dummy"))
    sb = StaticState.from_recording(b, label="baseline")
    sd = StaticState.from_recording(d, label="dummy")
    return b.rig, sb, replace(sd, added=None), np.array(b.truth["center_of_gravity"], float)


def perturbed(rig, rng):
    """rig.yaml as a survey with the default σ would give it: every anchor coordinate, cable
    length and dummy-position coordinate off by a normal draw of its σ."""
    cables = tuple(replace(c, ceiling_anchor=c.ceiling_anchor + rng.normal(0, DEFAULT_ANCHOR_STD, 3),
                           body_anchor=c.body_anchor + rng.normal(0, DEFAULT_ANCHOR_STD, 3),
                           length=c.length + rng.normal(0, DEFAULT_LENGTH_STD)) for c in rig.cables)
    dm = DummyMass(rig.dummy_mass.mass, rig.dummy_mass.position + rng.normal(0, DEFAULT_DUMMY_POSITION_STD, 3))
    return replace(rig, cables=cables, dummy_mass=dm)


def test_noise_only_sigma_is_unchanged(pair):
    rig, sb, sd, _ = pair
    full = estimate_cg(rig, sb, sd)
    exact = estimate_cg(rig, sb, sd, CgOptions.exact_geometry())
    # the noise-only σ is the exact-geometry fit's σ (the fit's σ before the geometry was in it)
    np.testing.assert_allclose(full.center_of_gravity_std_noise, exact.center_of_gravity_std, rtol=0.01)
    np.testing.assert_allclose(exact.center_of_gravity_std_noise, exact.center_of_gravity_std, rtol=1e-9)
    # ... and 0.038, 0.0072, 0.43 mm on this pair, as rig-identify cg printed before
    np.testing.assert_allclose(exact.center_of_gravity_std, [3.8e-5, 7.2e-6, 4.29e-4], rtol=0.02)
    # with 1 mm of geometry the height's σ is > 15x the noise's (the observation)
    assert full.center_of_gravity_std[2] > 15 * full.center_of_gravity_std_noise[2]
    assert full.geometry_std == {"anchors": 1e-3, "cable_lengths": 1e-3, "dummy_position": 1e-3, "dummy_mass": 0.0}


def test_budget_adds_up_to_sigma(pair):
    rig, sb, sd, _ = pair
    res = estimate_cg(rig, sb, sd)
    total = np.sqrt(sum(v**2 for v in res.budget.values()))
    np.testing.assert_allclose(total, res.center_of_gravity_std, rtol=1e-6)
    assert set(res.budget) == {"measurement_noise", "cable_lengths", "dummy_position", "ceiling_anchors",
                               "body_anchors"}
    # the height is limited by the survey: its systematic share is most of the variance
    assert res.weakly_determined["axis"] == "z" and res.weakly_determined["systematic_share"] > 0.8
    exact = estimate_cg(rig, sb, sd, CgOptions.exact_geometry())
    assert set(exact.budget) == {"measurement_noise"}
    np.testing.assert_allclose(exact.budget["measurement_noise"], exact.center_of_gravity_std, rtol=1e-6)


def test_sensitivity_is_the_derivative_of_the_estimate(pair):
    """∂CG/∂(rig.yaml value) means the same whether the input is fitted or taken as exact:
    moving rig.yaml's dummy position by 0.2 mm moves the estimate by the reported amount."""
    rig, sb, sd, _ = pair
    h = np.array([2e-4, -1e-4, 1e-4])
    moved = replace(rig, dummy_mass=DummyMass(rig.dummy_mass.mass, rig.dummy_mass.position + h))
    for opts in (CgOptions(), CgOptions.exact_geometry()):
        a, b = estimate_cg(rig, sb, sd, opts), estimate_cg(moved, sb, sd, opts)
        predicted = np.asarray(a.sensitivity["dummy_position"]) @ h
        np.testing.assert_allclose(b.center_of_gravity - a.center_of_gravity, predicted, rtol=0.05,
                                   atol=0.02 * np.abs(predicted).max())


def test_sigma_covers_the_truth_with_the_geometry_off_by_its_sigma(pair):
    """Monte Carlo over rig.yaml: 30 surveys of the same rig, each 1 mm (1 σ) off."""
    rig, sb, sd, truth = pair
    z, z_noise = [], []
    for seed in range(DRAWS):
        res = estimate_cg(perturbed(rig, np.random.default_rng(seed)), sb, sd)
        err = res.center_of_gravity - truth
        z.append(err / res.center_of_gravity_std)
        z_noise.append(err / res.center_of_gravity_std_noise)
        assert res.validation.verdict == "ok", (seed, res.validation.failed)
    z, z_noise = np.array(z), np.array(z_noise)
    assert np.all(np.abs(z) <= 3.0), np.abs(z).max(axis=0)
    rms = np.sqrt(np.mean(z**2, axis=0))
    assert np.all((rms > 0.6) & (rms < 1.4)), rms                # calibrated, not just wide
    # the noise-only σ would be wrong by an order of magnitude on every coordinate
    assert np.all(np.sqrt(np.mean(z_noise**2, axis=0)) > 10)
