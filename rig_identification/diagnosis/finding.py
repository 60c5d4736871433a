"""One admissible combination of effects made a finding (:func:`finding`): its one-parameter
errors placed by their exact profile likelihood, the final fit reweighted by its own
residual scales (iteratively reweighted least squares), each member's parameters and σ, the
physics the model lacks as the generalized wrench it adds, and each effect's plausibility
(the method as a whole: :mod:`~rig_identification.diagnosis.selection`).
"""
from __future__ import annotations

from dataclasses import dataclass
from dataclasses import replace as _replace

import numpy as np

from ..io.recording import Recording
from ..model.parametrisation import from_tensor
from .candidates import body_inertia
from .exact import MASSES, PROFILED, columns_of, exact_profile, mass_builder, residual_scales
from .model_extension import Fit, Model, fit_model
from .plausible import implausible, undetermined
from .residuals import channel_residuals, exciter_phase
from .result import Combination, EffectWrench
from .structural import gain_std
from .window import Window

REWEIGHT_ITER = 2     # reweighting iterations of the final fit (per-axis residual scales)


@dataclass(frozen=True)
class FinalFit:
    """The final (reweighted) fit of a finding and what it was made on, which
    :func:`~rig_identification.diagnosis.selection.diagnose` keeps of its first combination
    only (its residuals and series) and the public :class:`Combination` leaves out.

    fit: the fit (tensor, effect columns, covariance, residuals); model: the extended model it
    was fitted on (band, filters); window: the diagnosis window's streams, with the
    combination's corrections (t (N,) s); channels: the residual time series (N,) per channel
    (:func:`~rig_identification.diagnosis.residuals.channel_residuals`)."""

    fit: Fit
    model: Model
    window: Window
    channels: dict


def finding(ev: dict, rec: Recording, state: dict, build, kappa0: float, scales,
            cost0: dict, doubt: dict | None = None) -> tuple[Combination, FinalFit]:
    """One admissible combination ``ev`` of :func:`~rig_identification.diagnosis.selection.diagnose`'s
    joint search (its members, corrections, fit and evidence; ``state``, ``build``, ``kappa0``,
    ``scales``, ``cost0``: the search's) made a finding: each one-parameter rig or data error placed by
    its exact profile likelihood, the final fit reweighted by its own residual scales, every
    member's parameters (and σ) from it, the physics the model lacks as the wrench it adds,
    plausibility and determination (:func:`implausible`, :func:`undetermined`).  Returns the
    :class:`Combination` (its ``relative_std``:
    the relative σ of the tensor that the corrections fixed from outside the band leave, a
    structural mode's :func:`~rig_identification.diagnosis.structural.gain_std` at the band's
    centre) and its :class:`FinalFit` (the fit, model, window and channel residuals).
    doubt: (name, label) -> :func:`~rig_identification.diagnosis.distinguish.ambiguity`'s entry
    for the members the recording does not tell apart from a rival's; their effect entries get
    ``told_apart`` False, ``class``, ``candidates`` and ``tells_apart``."""
    keys, members = ev["keys"], ev["members"]
    free_kappa, elastic = ev["free_kappa"], ev["elastic"]
    st = {**state, "applied": dict(ev["applied"]), "elastic": elastic, "profiled": dict(ev["profiled"])}

    def bld(ap, el, pr=None, keep_stretch=False):
        return build(ap, el, st["profiled"] if pr is None else pr, keep_stretch or ev["keep_stretch"])

    w, M, cands = bld(st["applied"], elastic)
    cur_fit = ev["fit"]
    for m in members:
        if m["c"].name in PROFILED:
            st["cands"] = cands
            st["applied"], w, M, cands, cur_fit, _ = exact_profile(m["c"].key, st, mass_builder(bld, m["c"].key),
                                                                   keys, cost0, kappa0, free_kappa, scales,
                                                                   from_tensor(cur_fit.J), w)
    if any(m["c"].name in MASSES for m in members) and "steel" in state:
        # the trial re-tracks kept the steel stretch: fitted again with the mass in place
        w, M, cands = build(st["applied"], elastic, st["profiled"])
        cur_fit = fit_model(M, columns_of(cands, keys), kappa0, free_kappa, scales, from_tensor(cur_fit.J))
    # the screening weighted each axis by the baseline's residual scale, which the missing
    # physics inflated on some axes: the final fit is reweighted by its own residual scales
    # (iteratively reweighted least squares: the maximum-likelihood estimate with unknown
    # per-axis noise levels)
    for _ in range(REWEIGHT_ITER):
        sr, sa = residual_scales(M, cur_fit)[:2]
        cur_fit = fit_model(M, columns_of(cands, keys), kappa0, free_kappa, (sr, sa) + tuple(scales[2:]),
                            from_tensor(cur_fit.J))
    by = {cc.key: cc for cc in cands}
    entries, pos = [], 0
    tq_add, f_add, phys, share = np.zeros_like(w.omega), np.zeros_like(w.omega), [], {}
    for key in keys:
        c = by[key] if key in by else next(m["c"] for m in members if m["c"].key == key)
        evd = {k: v for k, v in ev["evidence"].get(key, {}).items() if k != "rms_reduction"}
        red = ev["evidence"].get(key, {}).get("rms_reduction", {})
        affected = sorted((k for k, r in red.items() if r >= 0.1), key=lambda k: -red[k])
        evd["rms_reduction"] = {k: round(red[k], 4) for k in affected[:8]}
        e = {"name": c.name, "parameters": {}, "parameters_std": {}, "evidence": evd}
        if doubt and key in doubt:
            e.update(told_apart=False, **{k: doubt[key][k] for k in ("class", "candidates", "tells_apart")})
            e["evidence"]["rivals"] = {"likelihood_ratios": doubt[key]["likelihood_ratios"], "bar": doubt[key]["bar"]}
        entries.append(e)
        if key[0] == "cable_elasticity":
            k = w.stiffness[np.isfinite(w.stiffness)]
            e["parameters"], e["parameters_std"] = {"stiffness": float(np.median(k))}, \
                {"stiffness": float(w.stiffness_std) if w.stiffness_std is not None else float("nan")}
            continue
        if c.gyroscopic:
            vals, stds = [cur_fit.kappa], [float(np.sqrt(max(cur_fit.cov[-1, -1], 0.0)))]
        else:
            vals = cur_fit.beta[pos:pos + len(c.columns)]
            stds = np.sqrt(np.clip(np.diag(cur_fit.cov)[6 + pos:6 + pos + len(c.columns)], 0, None))
            pos += len(c.columns)
        e["parameters"], e["parameters_std"] = c.report(vals, stds)
        if c.exact or c.gyroscopic:
            continue
        # the physics the model lacks (not an error of the data), as the wrench it adds
        phys.append(c.name)
        tq_c = np.zeros_like(w.omega)
        for b, col in zip(vals, c.columns):
            if col.rot_D is not None:
                tq_c += b * col.rot_D
            if col.tr_D is not None:
                f_add += b * w.mass * col.tr_D
        tq_add += tq_c
        share[c.name] = float(np.sqrt(np.mean(M.filt(tq_c) ** 2)) / max(np.sqrt(np.mean(M.filt(w.torque) ** 2)),
                                                                        1e-12))
    effect_wrench = EffectWrench(w.t.copy(), tq_add, f_add, tuple(phys)) if phys else None
    phase = exciter_phase(w)
    unbalance = None
    if phase is not None:
        ok = np.isfinite(phase)
        f_hz = abs(float(np.polyfit(w.t[ok], phase[ok], 1)[0])) / (2 * np.pi)
        unbalance = float(np.median(np.linalg.norm(w.f_exc, axis=1))) / (2 * np.pi * f_hz) ** 2
    for e in entries:
        why = implausible(e, rec.rig, share.get(e["name"]), unbalance, state.get("cg_covariance")) or undetermined(e)
        e["plausible"] = why is None
        if why is not None:
            e["implausible"] = why
        if e["name"] in share:
            e["evidence"]["moment_share"] = round(share[e["name"]], 4)
        e["evidence"]["combination"] = {"likelihood_ratio": ev["lam"], "dof": ev["dof"], "bic": ev["bic"]}
    entries.sort(key=lambda e: -e["evidence"].get("likelihood_ratio", 0.0))
    applied = without_inert(st["applied"])
    # the uncertainty of a correction fixed from outside the band (a structural mode's
    # shape): the relative error of the readings it leaves in the band, about the tensor's
    modes = state["retracked"].get("modes", {})
    f_c = float(np.sqrt(M.band[0] * M.band[1]))
    rel = float(np.sqrt(sum(gain_std(modes[k[1]], f_c) ** 2 for k in keys if k[0] == "structural_mode")))
    mu = float(applied.get(("cable_mass", ""), 0.0))
    body_rig = _replace(rec.rig, mass=rec.rig.mass + float(applied.get(("body_mass", ""), 0.0)))
    combination = Combination(effects=entries, applied=applied, effect_wrench=effect_wrench,
                              stiffness=w.stiffness.copy() if elastic else None,
                              inertia=body_inertia(cur_fit.J, body_rig, mu), covariance=np.array(cur_fit.cov[:6, :6]),
                              relative_std=rel, likelihood_ratio=ev["lam"], dof=ev["dof"], bic=ev["bic"],
                              keys=tuple(tuple(k) for k in ev["keys"]))
    return combination, FinalFit(cur_fit, M, w, channel_residuals(M, cur_fit))


def without_inert(applied: dict) -> dict:
    """``applied`` without the companions of corrections not made (the drift's knots, a
    mode's shape: they only say how to make them)."""
    out = {}
    for k, v in applied.items():
        if k == ("gyro_bias_drift", "knots") and ("gyro_bias_drift", "") not in applied:
            continue
        if k[0] == "structural_mode" and k[1].endswith(" shape") and (k[0], k[1][:-6]) not in applied:
            continue
        out[k] = v
    return out
