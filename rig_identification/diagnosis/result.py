"""The diagnosis's result types: :class:`Diagnosis` (what
:func:`~rig_identification.diagnosis.selection.diagnose` found, the JSON of ``rig-identify
diagnose``), :class:`Combination` (one admissible combination of effects, which the caller
validates and names) and :class:`EffectWrench` (the generalized wrench the diagnosed physics adds
to the measured one).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..io.verdict import KEYS
from ..model.parametrisation import from_tensor


@dataclass(frozen=True)
class EffectWrench:
    """The generalized wrench that the diagnosed physics adds to the measured one (the
    extended model's moment and force columns times their fitted parameters; Newton–Euler:
    J ω̇ + ω × Jω = M + M_effect, m a = F + F_effect).

    t (N,) s, absolute stamps of the diagnosis window; torque (N,3) N·m about the CG and force
    (N,3) N, body axes; names: the effects it holds."""

    t: np.ndarray
    torque: np.ndarray
    force: np.ndarray
    names: tuple

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(torque (M,3), force (M,3)) at the stamps ``t`` (M,) s: linear interpolation, the
        end values held outside the window."""
        tq = np.column_stack([np.interp(t, self.t, self.torque[:, k]) for k in range(3)])
        fc = np.column_stack([np.interp(t, self.t, self.force[:, k]) for k in range(3)])
        return tq, fc


@dataclass(frozen=True)
class Combination:
    """One admissible combination of effects, made a finding: what
    :func:`~rig_identification.diagnosis.finding.finding` reports of diagnose's joint fit with it
    (or :func:`~rig_identification.diagnosis.compliant_body.diagnosis_alternative` of the
    two-body fit), and what :func:`~rig_identification.pipeline.offline.with_diagnosis` needs to
    identify the recording again with it and validate that fit.

    effects: the members' entries, most significant first (dicts: ``name``, ``parameters`` and
    ``parameters_std`` in the units :func:`~rig_identification.io.export.effect_text` says,
    ``evidence`` (likelihood ratios, the combination's, the channels' residual RMS reductions),
    ``plausible``, ``implausible`` (why not, when not) and, for the compliant body, ``label``
    and ``advice``); the same dicts as :attr:`Diagnosis.effects` for the first combination and
    in the JSON.
    applied: every correction made to the data or the rig, the cables' mass included:
    (effect, label) -> value, what :func:`~rig_identification.diagnosis.candidates.corrected`
    takes.
    effect_wrench: the physics added to the model as the generalized wrench it adds to the
    measured one (body axes, about the CG), or None when the combination only corrects the data.
    stiffness: (n,) N/m, the cables' stiffness when their elasticity was found, else None.
    inertia: (3,3) kg·m², the body's inertia tensor about its CG, body axes, from the joint fit
    with the effects (the cables' share taken off when their mass was found); None for a
    hypothesis that gives no tensor (a compliant body not named).
    covariance: (6,6) kg²·m⁴ of the tensor's entries (:data:`~rig_identification.io.verdict.KEYS`
    order) in that joint fit, or None (a compliant body not named).
    relative_std: the relative σ of the tensor that corrections fixed from outside the fit band
    leave (a structural mode's shape: :func:`~rig_identification.diagnosis.structural.gain_std`
    at the band's centre); 0 when there are none.
    likelihood_ratio: the likelihood-ratio statistic of the combination against the rigid-body
    model (2 Δ log-likelihood, χ² with ``dof`` degrees of freedom under the rigid body: Wilks;
    :func:`~rig_identification.diagnosis.exact.likelihood_ratio`); dof: the parameters it adds;
    bic: its Bayesian information criterion relative to the rigid body's, −likelihood_ratio +
    dof · ln n (smaller is better; the alternatives' order).
    keys: the members' (effect, label) keys (with_diagnosis tries, after a validated
    combination, only its proper subsets).
    not_named: why the combination is never fitted again and never named (a hypothesis judged
    by its own test: the compliant body's), else None.
    """

    effects: list[dict]
    applied: dict
    effect_wrench: EffectWrench | None
    stiffness: np.ndarray | None
    inertia: np.ndarray | None
    covariance: np.ndarray | None
    relative_std: float
    likelihood_ratio: float
    dof: int
    bic: float
    keys: tuple[tuple[str, str], ...]
    not_named: str | None = None


@dataclass
class Diagnosis:
    """Result of :func:`~rig_identification.diagnosis.selection.diagnose`; :meth:`to_dict` is the
    JSON of ``rig-identify diagnose``."""

    mismatch: bool
    effects: list
    located: dict
    rms_before: dict
    rms_after: dict
    inertia_before: np.ndarray
    inertia_after: np.ndarray
    inertia_std_before: np.ndarray
    inertia_std_after: np.ndarray
    tried: list
    band: tuple
    model: str
    warnings: list = field(default_factory=list)
    series: dict = field(default_factory=dict)
    covariance_after: np.ndarray | None = None   # (6,6) of the entries of inertia_after, KEYS order
    # the sensor and rig errors removed from the data (key -> value, as
    # :func:`~rig_identification.diagnosis.candidates.corrected` takes)
    corrections: dict = field(default_factory=dict)
    # time-synchronous residual RMS per channel (None: no rotating exciter), and the revolutions averaged
    rms_sync_before: dict | None = None
    rms_sync_after: dict | None = None
    revolutions: float | None = None
    # the physics added to the model (not errors of the data), as the generalized wrench it
    # adds to the measured one along the window: :class:`EffectWrench` or None
    effect_wrench: "EffectWrench | None" = None
    # every correction made to the data or the rig (key -> value,
    # :func:`~rig_identification.diagnosis.candidates.corrected`; the cables' mass included), and the
    # cables' stiffness (n,) N/m when their elasticity was found
    applied: dict = field(default_factory=dict)
    stiffness: np.ndarray | None = None
    # the admissible combinations (:class:`Combination`), best (smallest BIC) first, the first
    # being the fields above; the caller validates them in that order
    alternatives: list[Combination] = field(default_factory=list)
    # every combination fitted: {"effects": [(name, label)], "likelihood_ratio", "dof", "bic",
    # "admissible", "why"}, by BIC
    joint: list = field(default_factory=list)
    # where the accelerometer departs from Newton's prediction from the load cells above the
    # fit band (:func:`~rig_identification.diagnosis.structural.out_of_band`)
    out_of_band: list = field(default_factory=list)

    def to_dict(self) -> dict:
        ent = lambda J: {k: float(x) for k, x in zip(KEYS, from_tensor(J))}  # noqa: E731
        return {"mismatch": self.mismatch, "effects": self.effects, "located": self.located,
                "residual_rms_before": self.rms_before, "residual_rms_after": self.rms_after,
                "inertia_about_cg_before": ent(self.inertia_before),
                "inertia_about_cg_after": ent(self.inertia_after),
                "inertia_std_before": {k: float(x) for k, x in zip(KEYS, self.inertia_std_before)},
                "inertia_std_after": {k: float(x) for k, x in zip(KEYS, self.inertia_std_after)},
                "candidates": self.tried, "band_hz": [float(x) for x in self.band], "model": self.model,
                "warnings": self.warnings,
                "residual_rms_synchronous_before": self.rms_sync_before,
                "residual_rms_synchronous_after": self.rms_sync_after,
                "synchronous_revolutions": self.revolutions,
                "alternatives": [{"effects": [e["name"] for e in a.effects], "likelihood_ratio": a.likelihood_ratio,
                                  "dof": a.dof, "bic": a.bic} for a in self.alternatives],
                "combinations": [{**j, "effects": [f"{n} {lab}".strip() for n, lab in j["effects"]]}
                                 for j in self.joint],
                "out_of_band": self.out_of_band}
