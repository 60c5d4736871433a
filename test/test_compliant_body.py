"""The compliant body: a sprung body on its suspension inside the carrying frame.

(The static CG fit's ``tilt_change`` check for a compliant body: test_cg_validation.py.)

* The two-body model (:mod:`rig_identification.estimation.two_body`): its time response is
  the apparent tensor of its frequency response, and it tends to the rigid body.
* The sprung body's reaction wrench (:func:`~rig_identification.diagnosis.compliant_body.effect_wrench_of`)
  is −Σ ℓ ℓᵀ jΩ G(jΩ) ω̂ in steady state; the exciter's speeds read from its force, and
  whether they sweep through the modes (:func:`~rig_identification.diagnosis.compliant_body.swept`).
* The gate (:func:`~rig_identification.diagnosis.not_rigid.two_body_reason`): the body may not
  be rigid only when nothing else explained the misfit and the rigid-body fit failed
  ``sub_bands`` or the exciter swept — never on a recording that passes (a clean one).
* ``rig-identify inertia`` (``with_diagnosis``) on test_validation's 45 s random rig with a
  68 %-sprung body and one exciter speed (its job shared): the unfitted hypothesis with the
  advice (lock the suspension, or ``diagnose --two-body``), never a tensor.
* ``rig-identify diagnose``'s lines for the experimental two-body fit (``--two-body``): the
  hypothesis and its one line of advice, never a tensor.  The fit itself on recordings (45–90 s
  of a minute each) is measured by ``bench/bench_compliant_body.py``, outside the suite: it only
  ever gives a hypothesis, and stays out of the main path until a bench trusts it.
"""
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import test_validation  # noqa: F401  (registers the "validation" jobs this module shares)
from conftest import gather
from scipy.spatial.transform import Rotation

from rig_identification.cli.diagnose import compliant_dict, compliant_lines
from rig_identification.cli.inertia import diagnosis_lines
from rig_identification.diagnosis import compliant_body as cbm
from rig_identification.diagnosis import not_rigid as nr
from rig_identification.diagnosis.result import Combination
from rig_identification.estimation import two_body as tb
from rig_identification.io.recording import TimeSeries

# --- the two-body model ---------------------------------------------------------------------------

MODES = tb.SprungModes(np.array([900.0, -20.0, 60.0, 2600.0, 5.0, 2900.0]),
                       np.array([[18.0, 0.0, 2.0], [0.0, 38.0, 0.0]]), np.array([1.6, 1.3]), np.array([0.2, 0.25]))


def test_two_body_response_is_the_apparent_tensor():
    """Driven by a sinusoidal integrated moment U at f, the model's ω in steady state is
    J_app(j2πf)⁻¹ U (J_app = J + Σ ℓℓᵀ G(j2πf)); J_app tends to the tensor at rest below the
    modes and to the frame's part J − Σ ℓℓᵀ far above them."""
    fs, f = 200.0, 1.1
    t = np.arange(0, 40.0, 1 / fs)
    U0 = np.array([30.0, -12.0 + 5j, 8j])
    U = (U0[None, :] * np.exp(2j * np.pi * f * t)[:, None]).real
    w = tb.respond(MODES, U, fs)
    expected = (np.linalg.solve(MODES.apparent(f), U0)[None, :] * np.exp(2j * np.pi * f * t)[:, None]).real
    late = t > 30.0                                          # the modes' start-up transient has died away
    np.testing.assert_allclose(w[late], expected[late], atol=2e-4 * np.abs(expected).max())
    np.testing.assert_allclose(MODES.apparent(1e-3), MODES.tensor, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(MODES.apparent(1e3).real, MODES.tensor - MODES.sprung_tensor, rtol=1e-4)


def test_two_body_without_participation_is_the_rigid_body():
    """ℓ = 0: ω = J⁻¹ U at every sample."""
    rigid = replace(MODES, participation=np.zeros((2, 3)))
    U = np.random.default_rng(3).standard_normal((500, 3)).cumsum(0)
    w = U @ np.linalg.inv(MODES.tensor).T
    np.testing.assert_allclose(tb.respond(rigid, U, 100.0), w, rtol=0, atol=1e-6 * np.abs(w).max())
    assert tb.frame_inertia_definite(MODES)
    assert not tb.frame_inertia_definite(replace(MODES, participation=np.array([[40.0, 0, 0], [0, 38.0, 0]])))


# --- the reaction wrench and the exciter's sweep ------------------------------------------------------

def test_reaction_wrench_is_the_apparent_tensor_minus_the_rest():
    """ω = Re(ω̂ e^{jΩt}) on the frame: in steady state the sprung body's reaction is
    −Σ ℓ ℓᵀ (jΩ G(jΩ)) ω̂ (q̇ = G ℓᵀω, M = −Σ ℓ q̈), so that J ω̇ − M_effect = J_app(jΩ) ω̇."""
    fs, f = 200.0, 1.4
    t = np.arange(0.0, 40.0, 1 / fs)
    w_hat = np.array([0.02, -0.01 + 0.005j, 0.004j])
    omega = (w_hat[None, :] * np.exp(2j * np.pi * f * t)[:, None]).real
    rig = SimpleNamespace(imu=SimpleNamespace(rotation=Rotation.identity()))
    sensors = SimpleNamespace(imu=TimeSeries(t, np.hstack([omega, np.zeros_like(omega)])))
    modes = [cbm.SprungMode("roll", 1.6, 0, 0.2, 0, MODES.participation[0], 0.3),
             cbm.SprungMode("pitch", 1.3, 0, 0.25, 0, MODES.participation[1], 0.3)]
    wr = cbm.effect_wrench_of(rig, sensors, modes)
    s = 2j * np.pi * f
    J_extra = MODES.apparent(f) - MODES.tensor                         # Σ ℓℓᵀ G(jΩ)
    expected = (-(J_extra @ (s * w_hat))[None, :] * np.exp(s * t)[:, None]).real
    late = t > 30.0
    np.testing.assert_allclose(wr.torque[late], expected[late], atol=2e-3 * np.abs(expected).max())
    assert wr.names == ("compliant_body",) and not np.any(wr.force)


def test_exciter_speeds_and_sweep():
    """A spin-up from rest to 3.5 Hz over 80 s reads as 0.1–3.4 Hz (the slow start's force
    ∝ speed² under 1 % left out) and sweeps through modes at 1.5 and 2.6 Hz; one speed
    (1.25 Hz) sweeps through none, and the reason says at which speed it ran."""
    fs = 200.0
    t = np.arange(0.0, 80.0, 1 / fs)
    ph = np.pi * 3.5 * t**2 / 80.0                                      # speed 3.5 t / 80 Hz
    A = 500.0 * (t / 80.0) ** 2
    sweep = SimpleNamespace(exciter=TimeSeries(t, np.column_stack([A * np.cos(ph), A * np.sin(ph)])))
    lo, hi = nr.exciter_speeds(sweep, 0.0, 80.0)
    assert 0.05 < lo < 0.6 and 3.3 < hi <= 3.5
    modes = [SimpleNamespace(axis="roll", frequency=1.5), SimpleNamespace(axis="pitch", frequency=2.6)]
    assert cbm.swept(modes, (lo, hi)) == ""
    ph1 = 2 * np.pi * 1.25 * t
    fixed = SimpleNamespace(exciter=TimeSeries(t, 200.0 * np.column_stack([np.cos(ph1), np.sin(ph1)])))
    speeds = nr.exciter_speeds(fixed, 0.0, 80.0)
    assert abs(speeds[0] - 1.25) < 0.01 and abs(speeds[1] - 1.25) < 0.01
    why = cbm.swept(modes, speeds)
    assert "at 1.25 Hz only" in why and "roll mode (1.50 Hz)" in why and "pitch mode (2.60 Hz)" in why


def _spin(t, speed_hz_of_t):
    """An exciter stream whose force turns at the given speed (Hz, a function of t)."""
    ph = 2 * np.pi * np.cumsum(speed_hz_of_t(t)) * (t[1] - t[0])
    return TimeSeries(t, 200.0 * np.column_stack([np.cos(ph), np.sin(ph)]))


def test_gate_runs_the_two_body_fit_only_when_it_can_matter():
    """The two-body fit runs when nothing of the ordinary library explained the misfit and the
    rigid-body fit failed ``sub_bands`` or the exciter swept; never when something explained it,
    nor without an exciter, nor on a fixed speed whose fit passed sub_bands."""
    t = np.arange(0.0, 80.0, 0.005)
    fixed = SimpleNamespace(rig=SimpleNamespace(exciter=object()),
                            sensors=SimpleNamespace(exciter=_spin(t, lambda t: np.full_like(t, 1.25))))
    sweep = SimpleNamespace(rig=fixed.rig, sensors=SimpleNamespace(exciter=_spin(t, lambda t: 0.3 + 3.2 * t / 80.0)))
    bare = SimpleNamespace(rig=SimpleNamespace(exciter=None), sensors=fixed.sensors)

    def result(*failed):
        return SimpleNamespace(validation=SimpleNamespace(failed=tuple(failed)), t_start=5.0, t_end=80.0)
    assert "sub_bands" in nr.two_body_reason(fixed, result("segments", "sub_bands"), explained=False)
    assert nr.two_body_reason(fixed, result("segments", "sub_bands"), explained=True) == ""
    assert nr.two_body_reason(bare, result("sub_bands"), explained=False) == ""
    assert nr.two_body_reason(fixed, result("whiteness", "input_correlation"), explained=False) == ""
    assert "swept" in nr.two_body_reason(sweep, result("whiteness"), explained=False)
    assert nr.two_body_reason(sweep, result("whiteness"), explained=True) == ""


# --- the candidate on simulated recordings ----------------------------------------------------------

# test_validation's "compliant" job (seed 7700, 45 s, a 68 %-sprung body; identified and diagnosed
# as rig-identify inertia --model pem does)
VALIDATION_JOB = ("validation", "compliant")


def test_inertia_says_the_body_may_not_be_rigid_without_fitting_it():
    """Through ``with_diagnosis`` (what ``rig-identify inertia`` does; the gate open: the
    rigid-body fit failed sub_bands, nothing of the library explained it): the hypothesis that
    the body is not rigid, unfitted — no parameters, no tensor, never named — and one line of
    advice: lock the suspension, or ``diagnose --two-body``."""
    truth, rigid, res = gather(*VALIDATION_JOB)[VALIDATION_JOB[1]]
    assert "sub_bands" in rigid.validation.failed and res.validation.verdict != "ok"
    assert res.diagnosis["effects"] == []
    hyp = [e for e in res.diagnosis["hypotheses"] if e["name"] == "compliant_body"]
    assert len(hyp) == 1
    entry = hyp[0]
    why = "the rigid-body fit's apparent inertia depends on the frequency (sub_bands failed)"
    assert entry["evidence"] == {"fitted": False, "why": why}
    assert entry["plausible"] is False and entry["parameters"] == {} and entry["implausible"].startswith("not fitted")
    advice = entry["advice"]
    assert advice.startswith("the body may not be rigid: ") and "lock the suspension" in advice
    assert "rig-identify diagnose RECORDING --model pem --two-body" in advice
    tried = [h for h in res.diagnosis["combinations_tried"] if [e["name"] for e in h["effects"]] == ["compliant_body"]]
    assert tried and tried[0]["not_named"] == entry["implausible"]
    assert f"advice: {advice}" in diagnosis_lines(res)
    assert any("compliant_body" in w for w in res.warnings)


def _named_not(e):
    """As diagnosis_alternative gives a sprung body it does not name: no tensor."""
    return Combination([e], {}, None, None, None, None, 0.0, 60.0, 4, -40.0, (("compliant_body", ""),),
                       not_named="a hypothesis")


def test_diagnose_command_says_the_hypothesis_in_one_advice_line():
    """``rig-identify diagnose``'s part for the two-body fit: nothing when the gate kept it off;
    the hypothesis and its advice line when it ran; said plainly when it found no sprung body."""
    assert compliant_lines(compliant_dict("", None, True)) == [] and compliant_dict("", None, True)["run"] is False
    # the gate open, the fit not asked for (rig-identify diagnose without --two-body): the unfitted hypothesis
    unfitted = compliant_dict("sub_bands failed", None, False)
    assert unfitted["run"] is False and unfitted["hypothesis"]["evidence"]["fitted"] is False
    lines = compliant_lines(unfitted)
    assert lines[0].startswith("hypothesis (not a finding): compliant_body: not fitted (sub_bands failed)")
    assert lines[1].startswith("advice: the body may not be rigid: sub_bands failed; lock the suspension")
    assert "--two-body" in lines[1] and len(lines) == 2
    entry = {"name": "compliant_body", "parameters": {"frequencies": [1.55, 1.1], "damping_ratio": [0.2, 0.25]},
             "parameters_std": {"frequencies": [0.05, 0.1], "damping_ratio": [0.02, 0.03]}, "plausible": False,
             "advice": "the body may not be rigid: …; lock the suspension (or sweep the exciter through the modes) "
                       "and record again"}
    lines = compliant_lines(compliant_dict("sub_bands failed", _named_not(entry), True))
    assert lines[0].startswith("hypothesis (not a finding): compliant_body: frequencies = ")
    assert lines[1] == f"advice: {entry['advice']}" and len(lines) == 2
    implausible = {k: v for k, v in entry.items() if k != "advice"}
    assert len(compliant_lines(compliant_dict("sub_bands failed", _named_not(implausible), True))) == 1
    none = compliant_lines(compliant_dict("sub_bands failed", None, True))
    assert len(none) == 1 and "no significant sprung body" in none[0]
