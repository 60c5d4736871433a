"""Centre of gravity from the static experiment (thesis chapter 2, section 2.2), generalised.

The suspended body (vehicle + carrying frame) is recorded at rest twice: without (the
*baseline*) and with a dummy mass of known mass and position (the *dummy* state).  The
thesis (eqs. 2.6–2.25) found the pose of each state from the cable lengths and two
inclinometer angles, then the cable tensions and the CG from the equilibrium equations.
Our rig also measures every cable's tension, which over-determines the problem; this
package fits everything at once, weighted by the measured noise:

**Model.**  State s (baseline, dummy, ...) is at rest in the pose (R_s, p_s) (rotation
body -> world, world position of the body-frame origin) with cable tensions T_s (N,).
Given the global unknowns θ -- the CG ``c`` (body frame), the suspended mass ``m``, the
common compliance ``C`` = 1/k of the cables whose stiffness rig.yaml does not give, the
load-cell gain ``κ`` (true tension = κ · reading), optionally inclinometer zero offsets
and the cable lengths -- the state solves the N + 6 equations

* cable lengths |A_i - p_s - R_s b_i| = L_i + C_i T_i      (thesis eqs. 2.13–2.19, stretched)
* force balance Σ T_i u_i + (m + m_add,s) g = 0           (eqs. 2.20–2.22)
* moment balance Σ R_s b_i × T_i u_i + R_s (m c + Σ m_d d) × g = 0   (eqs. 2.23–2.25, about
  the body origin; the dummy term is the thesis's combined-CG expression of section 2.2.3)

for its N + 6 unknowns (pose 6, tensions N): Newton with the analytic Jacobian.  The
estimate minimises the normalised misfit of what the rig measures -- the mean tensions
(load cells), the two inclinometer elevations (c31, c32 of eq. 2.6), optionally the
accelerometer's gravity direction, and the scale's mass reading as a prior -- over θ
(scipy ``least_squares``, Jacobian by the implicit-function theorem).  The covariance of θ
is (JᵀJ)⁻¹ with residuals divided by the noise σ of each mean (the samples' scatter /
sqrt(n), each state tested for stationarity first).

**The rig's geometry as surveyed.**  rig.yaml's anchors, cable lengths and dummy position are
measured, not known: by default each coordinate and length carries σ = 1 mm
(:data:`DEFAULT_ANCHOR_STD` ...; :class:`CgOptions`).  They are fitted too, each with its
rig.yaml value as a prior of that σ (a pseudo-measurement, the Gauss–Markov / "solve-for"
treatment of systematic parameters), so ``center_of_gravity_std`` holds both the noise and
the geometry; ``center_of_gravity_std_noise`` is the σ with the geometry taken as exact (the
same Jacobian, measurement rows and the other unknowns only), and ``budget`` splits the
covariance G Gᵀ (G = (JᵀJ)⁻¹Jᵀ, CG rows) by the rows' sources, so the shares add in
quadrature to the σ.  On the reference pair 1 mm of geometry makes the CG height's σ 22× the
noise's; a Monte Carlo over rig.yaml surveys off by that σ (test/test_cg_uncertainty.py)
finds the normalised errors' RMS near 1.

**Model validation** (:class:`CgValidation`): the residuals' covariance under the model is
I − U Uᵀ (U: left singular vectors of the weighted Jacobian, the linearised least-squares
result); the inclinometer's tilt change between the states and its mean level are tested
against it (Wald statistics), with the fit's χ² and the scale-vs-load-cell mass.

Because the tensions are predicted, not plugged in, the same code runs the thesis's
method (no load cells: inclinometers only) and any number of cables N >= 3 in any
geometry.  The CG height is found only through the tilt change the dummy mass causes, so
it is the poorly determined coordinate (:attr:`CgResult.weakly_determined`);
:func:`plan_static_test` predicts the CG σ of a planned test and recommends one.

Frames and units (docs/recording_format.md): world z up, gravity (0, 0, -g); body frame fixed
to the carrying frame; SI units (m, kg, N, rad, s).  Errors: :class:`StaticsError` (a
``ValueError``) with one clear message.

**Modules** (each imports only the ones listed before it; this package re-exports the public
names of the fit's modules — the CG's twenty-odd importers use ``from rig_identification.statics
import X``):

* :mod:`.state` -- a static state: every stream averaged over a window at rest and tested for
  stationarity (:class:`StaticState`, :class:`StreamStats`); :class:`StaticsError`;
* :mod:`.model` -- the model above: one state's equilibrium equations, their Jacobian, the
  Newton solve and the predicted measurements (:class:`~.model.StaticModel`,
  :class:`~.model.GlobalUnknowns`); :class:`CgOptions` and the survey σ defaults; the forward
  model :func:`static_equilibrium`;
* :mod:`.validation` -- model validation of a fit (:class:`CgValidation`);
* :mod:`.result` -- the estimate (:class:`CgResult`, :class:`StatePose`) and its JSON schema;
* :mod:`.checks` -- the states checked around the fit (taut cables, a pose per state, the dummy's
  load and tilt; no stream contradicting the fitted equilibrium);
* :mod:`.estimation` -- the fit, :func:`estimate_cg`;
* :mod:`.plan` -- design of the static test (:class:`SensorNoise`, :func:`predict_cg_std`,
  :class:`CgPlan`, :class:`PlanLimits`, :func:`plan_static_test`);
* :mod:`.capture` -- live capture of the states (the identifier node's CG services);
* :mod:`.handover` -- the CG handed on: a saved result read back, rig.yaml written with the CG
  (not re-exported).
"""
from importlib import import_module
from typing import Any

#: Where each public name lives; the submodule is imported when the name is first used (PEP 562),
#: so that reading a saved CG (:mod:`.handover`) does not load the fit, its checks and the planner.
_HOME = {
    "estimate_cg": "estimation",
    **dict.fromkeys(("DEFAULT_ANCHOR_STD", "DEFAULT_DUMMY_POSITION_STD", "DEFAULT_LENGTH_STD", "CgOptions",
                     "static_equilibrium"), "model"),
    **dict.fromkeys(("CgPlan", "PlanLimits", "SensorNoise", "candidate_positions", "plan_static_test",
                     "predict_cg_std"), "plan"),
    **dict.fromkeys(("CG_RESULT_SCHEMA", "CG_RESULT_SCHEMA_VERSION", "CG_RESULT_UNITS", "CgResult", "StatePose"),
                    "result"),
    **dict.fromkeys(("StaticsError", "StaticState", "StreamStats"), "state"),
    **dict.fromkeys(("CG_MODEL_CHECKS", "CG_VERDICTS", "VALIDATION_SIGMA", "CgValidation"), "validation"),
}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(f".{_HOME[name]}", __name__), name)


__all__ = ["CG_MODEL_CHECKS", "CG_RESULT_SCHEMA", "CG_RESULT_SCHEMA_VERSION", "CG_RESULT_UNITS", "CG_VERDICTS",
           "DEFAULT_ANCHOR_STD", "DEFAULT_DUMMY_POSITION_STD", "DEFAULT_LENGTH_STD", "VALIDATION_SIGMA", "CgOptions",
           "CgPlan", "CgResult", "CgValidation", "PlanLimits", "SensorNoise", "StatePose", "StaticState",
           "StaticsError", "StreamStats", "candidate_positions", "estimate_cg", "plan_static_test",
           "predict_cg_std", "static_equilibrium"]
