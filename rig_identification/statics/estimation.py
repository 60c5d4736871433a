"""The CG estimate of the static experiment: :func:`estimate_cg` (thesis section 2.2, eqs.
2.6–2.25, generalised; the method is described in :mod:`rig_identification.statics`).

The fit minimises the normalised misfit of what the rig measures in every state over the
global unknowns (scipy ``least_squares``, Jacobian by the implicit-function theorem through
:class:`~rig_identification.statics.model.StaticModel`), the rig's geometry fitted with its
survey σ as priors; it reports the covariance, the σ budget, the sensitivities and the model
validation, and rejects contradictory input with a
:class:`~rig_identification.statics.state.StaticsError`.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2 as _chi2

from ..io.rig import DummyMass, Rig
from ..io.verdict import Check
from .checks import (
    SLACK_FRACTION,
    check_dummy_load,
    check_taut,
    check_tilt_change,
    initial_pose,
    stream_misfits,
    vertical_loads,
)
from .model import DEFAULT_COMPLIANCE, CgOptions, GlobalUnknowns, StaticModel, Z, skew
from .result import CgResult, StatePose
from .state import StaticsError, StaticState
from .validation import CHI2_P_WARN, validate_fit

MASS_COVERAGE = 3.0              # mass disagreement warning: |Δ| > 3 σ combined
# contradictory geometry: the fit's χ² exceeds its dof by more than 20² (a 20 σ misfit, as the
# per-stream contradiction checks) and it needed an input moved by > 10 of its σ and > 5 mm
CONTRADICTION_CHI2 = 400.0
TOL_GEOMETRY = 5e-3              # m


# --- the estimator --------------------------------------------------------------------------------

def _added(rig: Rig, st: StaticState, is_baseline: bool) -> tuple[DummyMass, ...]:
    if st.added is not None:
        return st.added
    if is_baseline:
        return ()
    if rig.dummy_mass is None:
        raise StaticsError(f"{rig.source}: the rig description has no dummy_mass (mass and position of "
                           "the dummy mass of the static experiment)")
    return (rig.dummy_mass,)


def estimate_cg(rig: Rig, baseline: StaticState, dummy: StaticState | Sequence[StaticState],
                options: CgOptions | None = None) -> CgResult:
    """CG of the suspended body from a baseline and one or more dummy-mass static states.

    rig: the rig description (its ``center_of_gravity`` is ignored; ``dummy_mass`` is used
    for a dummy state whose ``added`` is ``None``).  baseline: the body alone (its CG is the
    one reported); dummy: the body with the dummy mass(es) ``added`` (a list of states for
    several dummy positions).  Thesis section 2.2, eqs. 2.6–2.25, generalised to N >= 3
    cables, stretched cables, load cells (see the docstring of :mod:`rig_identification.statics`).

    options: :class:`CgOptions` (default: load cells and inclinometer, the rig's geometry
    and mass with rig.yaml's survey σ, :meth:`CgOptions.from_survey`).

    Returns :class:`CgResult`: CG (3,) body frame m with σ (noise and geometry) and the σ of
    the noise alone, the σ budget, the sensitivities and the :class:`CgValidation` (a failed
    ``tilt_change`` or ``inclinometer_level`` check adds a warning).  Raises
    :class:`StaticsError`: a slack cable, a dummy mass that changed neither the load nor the
    inclination, angles outside the geometry's reach, a moving body, contradictory geometry or
    data (a stream misfit of > 20 σ, or a fit that needs a systematic input moved by > 10 of
    its σ and > 5 mm with χ² > dof + :data:`CONTRADICTION_CHI2`: the message names the input).
    """
    opts = options or CgOptions.from_survey(rig.survey)
    dummies = [dummy] if isinstance(dummy, StaticState) else list(dummy)
    if not dummies:
        raise StaticsError("at least one dummy-mass state is needed")
    states = [baseline] + dummies
    added = [_added(rig, s, i == 0) for i, s in enumerate(states)]
    m_add = np.array([sum(d.mass for d in a) for a in added])
    w_add = [sum((d.mass * d.position for d in a), np.zeros(3)) for a in added]
    warnings: list[str] = []
    for s in states:
        warnings += s.warnings

    have_T = opts.use_load_cells and all(s.tensions is not None for s in states)
    have_e = opts.use_inclinometer and rig.inclinometer is not None and all(s.elevations is not None for s in states)
    have_a = opts.use_accelerometer and all(s.specific_force is not None for s in states)
    if opts.use_inclinometer and rig.inclinometer is not None and not have_e:
        warnings.append("no inclinometer data in every state: fitted without the inclinometer")
    if not have_T and not have_e:
        raise StaticsError("neither load cells nor an inclinometer: the static experiment needs at least one")
    if all(np.allclose(w, 0) and m == 0 for w, m in zip(w_add, m_add)):
        raise StaticsError("no state carries a dummy mass (dummy_mass missing or zero)")
    tens = [s.tensions_for(rig) if have_T else None for s in states]

    # --- input checks: slack cables, the pose of each state, the dummy's load and tilt
    if have_T:
        check_taut(rig, states, [t[0] for t in tens])
    poses = [initial_pose(rig, None if t is None else t[0], s.elevations if have_e else None, s.label)
             for s, t in zip(states, tens)]
    if have_T:
        Wz = vertical_loads(rig, [t[0] for t in tens], poses)
        warnings += check_dummy_load(rig, states, Wz, m_add)
    check_tilt_change(states, poses, have_e)

    model = StaticModel(rig, opts, have_T, have_e, have_a, len(states))
    lay = model.layout
    # --- measured values and σ per state
    meas, sig = [], []
    for s, t in zip(states, tens):
        mv, sv = [], []
        if have_T:
            mv.append(t[0])
            sv.append(np.maximum(t[1], 1e-7 * np.abs(t[0]) + 1e-9))
        if have_e:
            mv.append(s.elevations)
            sv.append(np.maximum(s.elevations_std, 1e-9))
        if have_a:
            mv.append(s.specific_force)
            sv.append(np.maximum(s.specific_force_std, 1e-8))
        meas.append(np.concatenate(mv))
        sig.append(np.concatenate(sv))
    scale_std = opts.scale_std if opts.scale_std is not None else rig.survey.mass_std(rig.mass)

    # --- start values: mass and gain from the load cells, CG from the linearised moment balance
    if have_T:
        m_lc0 = Wz[0] / rig.gravity
        kappa0 = 1.0
        if lay.i_k is not None:
            dm = [(Wd - Wz[0]) / rig.gravity for Wd in Wz[1:]]
            kappa0 = float(np.mean([md / d for md, d in zip(m_add[1:], dm) if d > 0]))
        m0 = kappa0 * m_lc0
    else:
        m0, kappa0 = rig.mass, 1.0
    comp0 = np.where(model.known, model.comp_known, DEFAULT_COMPLIANCE if lay.i_C is not None else 0.0)
    A, b = [], []
    for i, ps in enumerate(poses):
        R = ps.rotation.as_matrix()
        if have_T:
            rb = rig.body_anchors @ R.T
            v = rig.ceiling_anchors - ps.position - rb
            f = kappa0 * tens[i][0][:, None] * v / np.linalg.norm(v, axis=1)[:, None]
            Mc = np.cross(rb, f).sum(0) + np.cross(R @ w_add[i], model.gv)
            A.append(-m0 * skew(model.gv) @ R)
            b.append(-Mc)
    if A:
        c0 = np.linalg.lstsq(np.vstack(A), np.concatenate(b), rcond=None)[0]
    else:
        c0 = rig.body_anchors.mean(0) - np.array([0.0, 0.0, 1.0])
    fixed = GlobalUnknowns(c0, comp0, m0, kappa0, np.zeros(2), rig.cable_lengths.copy(),
                           np.zeros((len(states), 3)), np.zeros(len(states)))
    y_cache = []
    for i, ps in enumerate(poses):
        T0 = kappa0 * tens[i][0] if have_T else np.full(model.n, (m0 + m_add[i]) * rig.gravity / model.n)
        y_cache.append((ps.rotation.as_matrix(), ps.position.copy(), T0))

    cache: dict = {}

    # the systematic inputs q (rig.yaml's values): the first dummy's position (3) and mass (1),
    # the cable lengths (N), the ceiling anchors (3N, world) and the body anchors (3N, body)
    n3 = 3 * model.n
    q_slices = {"dummy_position": slice(0, 3), "dummy_mass": slice(3, 4), "cable_lengths": slice(4, 4 + model.n),
                "ceiling_anchors": slice(4 + model.n, 4 + model.n + n3),
                "body_anchors": slice(4 + model.n + n3, 4 + model.n + 2 * n3)}
    n_q = 4 + model.n + 2 * n3

    def evaluate(th: np.ndarray, consider: bool = False):
        """(normalised residuals r, ∂r/∂θ (scaled), per-state solutions, globals, row groups);
        with ``consider``: ∂r/∂q (rows of r, n_q) of the systematic inputs' rig.yaml values."""
        key = th.tobytes()
        if key in cache and not consider:
            return cache[key]
        gl = model.unpack(th, fixed)
        r_all, J_all, sol, C_all = [], [], [], []
        for i in range(len(states)):
            # the added masses, with the fitted offsets of the dummy's mass and position
            ma = m_add[i] + gl.dm[i]
            dbar = w_add[i] / m_add[i] if m_add[i] > 0 else np.zeros(3)
            wa = ma * (dbar + gl.dd[i])
            R, p, T = model.solve_state(gl, ma, wa, y_cache[i], states[i].label)
            y_cache[i] = (R, p, T)
            E, Fy, part = model.equations(R, p, T, gl, ma, wa, jac=True)
            pred, Dy, Dk, Do = model.predict(R, T, gl)
            # dy/dθ_phys by the implicit-function theorem
            Fth = np.zeros((len(E), lay.n))
            Fth[:, :3] = part.c
            if lay.i_C is not None:
                Fth[:, lay.i_C] = part.C
            Fth[:, lay.i_m] = part.m
            if lay.i_L is not None:
                Fth[:, lay.i_L] = part.L
            if i > 0 and lay.i_dd is not None:
                Fth[:, lay.i_dd[i - 1]] = part.w_add * ma
            if i > 0 and lay.i_dm is not None:
                Fth[:, lay.i_dm[i - 1]] = part.m_add + part.w_add @ (dbar + gl.dd[i])
            if lay.i_A is not None:
                Fth[:, lay.i_A] = part.A
                Fth[:, lay.i_B] = part.B
            try:
                dy = -np.linalg.solve(Fy, Fth)
            except np.linalg.LinAlgError:
                dy = -np.linalg.lstsq(Fy, Fth, rcond=None)[0]
            Jp = Dy @ dy
            if consider:   # the same through the equations, for the rig.yaml values q
                Fq = np.zeros((len(E), n_q))
                if i == 1:
                    Fq[:, 0:3] = part.w_add * ma
                    Fq[:, 3] = part.m_add + part.w_add @ (dbar + gl.dd[i])
                Fq[:, q_slices["cable_lengths"]] = part.L
                Fq[:, q_slices["ceiling_anchors"]] = part.A
                Fq[:, q_slices["body_anchors"]] = part.B
                try:
                    dq = -np.linalg.solve(Fy, Fq)
                except np.linalg.LinAlgError:
                    dq = -np.linalg.lstsq(Fy, Fq, rcond=None)[0]
                C_all.append(-(Dy @ dq) / sig[i][:, None])
            if lay.i_k is not None:
                Jp[:, lay.i_k] += Dk
            if lay.i_off is not None:
                Jp[:, lay.i_off] += Do
            r_all.append((meas[i] - pred) / sig[i])
            J_all.append(-Jp / sig[i][:, None])
            sol.append((R, p, T, pred))
        # priors: the scale's mass only without load cells (with them, the load cells weigh the
        # body, calibrated by the dummy mass; the scale is then a cross-check, see below); the
        # systematic inputs fitted with their σ (offsets from rig.yaml's values)
        groups = [("measurement_noise", sum(len(x) for x in r_all))]
        pr, Jl = [], []

        def prior(name: str, idx, value: np.ndarray, std: float) -> None:
            idx = np.ravel(idx)
            pr.append(np.ravel(value) / std)
            Jd = np.zeros((len(idx), lay.n))
            Jd[np.arange(len(idx)), idx] = 1.0 / std
            Jl.append(Jd)
            groups.append((name, len(idx)))

        if not have_T:
            prior("scale", [lay.i_m], np.array([gl.m - rig.mass]), scale_std)
        if lay.i_L is not None:
            prior("cable_lengths", lay.i_L, gl.L - model.L0, opts.length_std)
        if lay.i_dd is not None:
            prior("dummy_position", lay.i_dd, gl.dd[1:], opts.dummy_position_std)
        if lay.i_dm is not None:
            prior("dummy_mass", lay.i_dm, gl.dm[1:], opts.dummy_mass_std)
        if lay.i_A is not None:
            prior("ceiling_anchors", lay.i_A, gl.A - model.A, opts.anchor_std)
            prior("body_anchors", lay.i_B, gl.B - model.b, opts.anchor_std)
        r = np.concatenate(r_all + pr)
        J = np.vstack(J_all + Jl) * lay.scale_arr[None, :]
        if consider:
            return np.vstack(C_all + [np.zeros((sum(len(x) for x in pr), n_q))])
        cache.clear()
        cache[key] = (r, J, sol, gl, groups)
        return cache[key]

    th0 = model.pack(fixed)
    sol = least_squares(lambda th: evaluate(th)[0], th0, jac=lambda th: evaluate(th)[1], method="lm",
                        x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
    r, J, solved, gl, groups = evaluate(sol.x)
    # covariance (column-scaled for conditioning)
    cn = np.linalg.norm(J, axis=0)
    cn[cn == 0] = 1.0
    Js = J / cn
    U, S, Vt = np.linalg.svd(Js, full_matrices=False)
    if S[-1] < 1e-10 * S[0]:
        bad = [lay.names[i] for i in np.argsort(-np.abs(Vt[-1]))[:2]]
        raise StaticsError(f"the static states do not determine {' and '.join(bad)} (singular fit); "
                           "use a dummy mass that tilts the body, with load cells or an inclinometer")
    cov_s = (Vt.T / S**2) @ Vt
    cov = cov_s / np.outer(cn, cn) * np.outer(lay.scale_arr, lay.scale_arr)
    dof = len(r) - lay.n
    chi2 = float(r @ r)
    infl = 1.0
    poor_fit = None       # the warning, completed once the validation has named the cause
    if dof > 0:
        pval = float(_chi2.sf(chi2, dof))
        if pval < CHI2_P_WARN:
            if opts.inflate:
                infl = math.sqrt(chi2 / dof)
            poor_fit = (f"the data fit the static model poorly (χ² = {chi2:.1f} for {dof} degrees of "
                        f"freedom, p = {pval:.1e})" + (f"; σ inflated ×{infl:.2f}" if infl > 1 else ""))
            warnings.append(poor_fit)
    cov = cov * infl**2
    # the estimator's gain G = (JᵀJ)⁻¹Jᵀ, CG rows, physical units: δc = -G δr
    G = ((Vt.T / S) @ U.T)[:3] / cn[:3, None] * lay.scale_arr[:3, None]
    # CG change per unit change of rig.yaml's value of each systematic input (fitted or not):
    # δc = -G (∂r/∂q) δq
    Sq = -G @ evaluate(sol.x, consider=True)
    sens = {k: (Sq[:, sl] if k != "dummy_mass" else Sq[:, sl][:, 0]) for k, sl in q_slices.items()}
    # σ budget: the covariance G Gᵀ split by the rows' sources (they add up to it)
    budget, k0 = {}, 0
    for name, nrows in groups:
        g = G[:, k0:k0 + nrows]
        budget[name] = infl * np.sqrt(np.sum(g**2, axis=1))
        k0 += nrows
    # the σ of the measurement noise alone, the systematic inputs taken as exact (their values
    # as fitted): the fit's Jacobian restricted to the measurement (and scale) rows and the other unknowns
    rows = np.r_[0:groups[0][1]]
    if not have_T:
        rows = np.r_[rows, groups[0][1]]
    Jn = J[np.ix_(rows, lay.core)]
    cnn = np.linalg.norm(Jn, axis=0)
    cnn[cnn == 0] = 1.0
    _, Sn, Vnt = np.linalg.svd(Jn / cnn, full_matrices=False)
    cov_n = (Vnt.T / Sn**2) @ Vnt / np.outer(cnn, cnn) * np.outer(lay.scale_arr[lay.core], lay.scale_arr[lay.core])
    c_std_noise = infl * np.sqrt(np.diag(cov_n)[:3])

    # --- contradiction check in physical units; slack in the fitted model
    stream_names = (["load_cells"] if have_T else []) + (["inclinometer"] if have_e else []) \
        + (["accelerometer"] if have_a else [])
    poses_out = []
    for i, (s, (R, p, T, pred)) in enumerate(zip(states, solved)):
        if T.min() < SLACK_FRACTION * (gl.m + m_add[i]) * rig.gravity / model.n:
            j = int(np.argmin(T))
            raise StaticsError(f"{s.label}: cable {rig.cable_names[j]} would be slack at the fitted equilibrium "
                               f"(tension {T[j]:.1f} N): contradictory geometry or data")
        res = stream_misfits(s.label, rig, stream_names, meas[i], pred, sig[i])
        poses_out.append(StatePose(s.label, p, R, T, float(m_add[i]), s.window, res))

    # --- systematic inputs the data need moved far beyond their σ: contradictory rig.yaml
    dev = _input_deviations(gl, model, opts, rig, [s.label for s in states])
    if (dev and chi2 > dof + CONTRADICTION_CHI2 and abs(dev[0][1]) > 10 * dev[0][2]
            and abs(dev[0][1]) > TOL_GEOMETRY):
        top = "; ".join(f"{nm} {d * 1e3:+.1f} mm (σ {sd * 1e3:g} mm)" for nm, d, sd in dev[:3])
        raise StaticsError(f"the static states contradict rig.yaml's geometry: the best fit (χ² = {chi2:.0f} for "
                           f"{dof} degrees of freedom) needs {top} from rig.yaml's values: contradictory geometry or "
                           "data "
                           "(check rig.yaml's anchors, cable lengths and dummy_mass; or give their real σ with "
                           "--anchor-std, --length-std, --dummy-position-std)")
    c = gl.c
    cc = cov[:3, :3]
    c_std = np.sqrt(np.diag(cc))
    # --- masses
    m_lc = m_lc_sd = None
    if have_T:
        # at the baseline pose the load cells and inclinometer give with rig.yaml's geometry
        # (independent of the CG fit, whose fitted anchors would trade the weight for the geometry)
        ps = poses[0]
        v = rig.ceiling_anchors - (ps.position + ps.rotation.apply(rig.body_anchors))
        uz = v[:, 2] / np.linalg.norm(v, axis=1)
        m_lc = float(tens[0][0] @ uz / rig.gravity)
        m_lc_sd = float(np.sqrt(np.sum((tens[0][1] * uz) ** 2)) / rig.gravity)
        comb = math.hypot(m_lc_sd, scale_std)
        if abs(m_lc - rig.mass) > MASS_COVERAGE * comb:
            cal = ""
            if lay.i_k is not None:
                cal = (f"; calibrated by the dummy mass (gain {gl.kappa:.5f}) they weigh "
                       f"{gl.m:.2f} ± {math.sqrt(cov[lay.i_m, lay.i_m]):.2f} kg")
            warnings.append(f"mass: the load cells imply {m_lc:.2f} ± {m_lc_sd:.2f} kg, the scale read "
                            f"{rig.mass:.2f} kg (assumed σ {scale_std:.2f} kg): they disagree by "
                            f"{abs(m_lc - rig.mass) / comb:.1f} σ (> {MASS_COVERAGE:g} σ){cal}")
    m_sd = float(math.sqrt(cov[lay.i_m, lay.i_m]))
    kap = kap_sd = None
    if lay.i_k is not None:
        kap, kap_sd = float(gl.kappa), float(math.sqrt(cov[lay.i_k, lay.i_k]))
    k_fit = k_sd = C = C_sd = None
    if lay.i_C is not None:
        C = float(gl.comp[~model.known].mean())
        C_sd = float(math.sqrt(cov[lay.i_C, lay.i_C]))
        if C > 3 * C_sd:
            k_fit, k_sd = 1.0 / C, C_sd / C**2
        if C < -3 * C_sd:
            warnings.append(f"the fitted cable compliance is negative ({C:.2e} ± {C_sd:.1e} m/N): the cables "
                            "seem to shorten under load; check the cable lengths")
    off = gl.off.copy() if lay.i_off is not None else None
    weak = _weakness(cc, rig, solved, have_e)
    ax = "xyz".index(weak["axis"])
    sys_var = sum(float(v[ax]) ** 2 for k, v in budget.items() if k not in ("measurement_noise", "scale"))
    weak["systematic_share"] = sys_var / max(float(cc[ax, ax]), 1e-300)
    if weak["systematic_share"] > 0.5 and weak["text"].endswith("longer averaging reduce it"):
        weak["text"] = weak["text"][:weak["text"].rindex(";")] + (
            f"; the rig's geometry as surveyed makes {100 * weak['systematic_share']:.0f} % of its variance "
            "(σ budget): "
            "a more precise survey of the anchors, cable lengths and dummy position reduces it, longer averaging "
            "hardly does")
    mass_check = None
    if m_lc is not None:
        comb = math.hypot(m_lc_sd, scale_std)
        z = abs(m_lc - rig.mass) / comb
        mass_check = Check("mass", z, MASS_COVERAGE, bool(z <= MASS_COVERAGE),
                           f"load cells {m_lc:.2f} ± {m_lc_sd:.2f} kg against the scale's {rig.mass:.2f} ± "
                           f"{scale_std:.2f} kg: {z:.1f} σ (a cross-check: the CG fit uses the load cells "
                           "calibrated by the dummy mass)")
    incl_rows = []
    if have_e:
        k0 = 0
        o = model.n if have_T else 0
        for i in range(len(states)):
            incl_rows.append((k0 + o, k0 + o + 1, sig[i][o:o + 2]))
            k0 += len(meas[i])
    validation = validate_fit(r, U, incl_rows, [s.label for s in states], chi2, int(dof), mass_check,
                              opts.fit_inclinometer_offset)
    named = [ck for ck in validation.checks if ck.passed is False and ck.name in ("tilt_change", "inclinometer_level")]
    if poor_fit is not None:
        hint = ("; see the failed check(s) " + ", ".join(ck.name for ck in named) if named else
                f"; if rig.yaml's geometry is less certain than the σ assumed (anchors {opts.anchor_std * 1e3:g} mm, "
                f"cable lengths {opts.length_std * 1e3:g} mm, dummy position {opts.dummy_position_std * 1e3:g} mm), "
                "give larger ones (--anchor-std, --length-std, --dummy-position-std)")
        warnings[warnings.index(poor_fit)] = poor_fit + hint
    for ck in named:
        warnings.append(f"model validation: check {ck.name} failed: {ck.detail}")
    geo = opts.geometry_std()
    return CgResult(c.copy(), c_std, cc, float(rig.mass), float(scale_std), m_lc, m_lc_sd, float(gl.m), m_sd,
                    kap, kap_sd, k_fit, k_sd, C, C_sd, off, poses_out, chi2, int(dof), infl, weak, warnings,
                    list(lay.names), cov, stream_names, sens, center_of_gravity_std_noise=c_std_noise,
                    geometry_std=geo, budget=budget, validation=validation)


def _input_deviations(gl: GlobalUnknowns, model: StaticModel, opts: CgOptions, rig: Rig,
                      labels: list[str]) -> list[tuple[str, float, float]]:
    """The fitted systematic inputs' changes from rig.yaml's values: (name, change m, σ m),
    largest change over σ first; empty when none is fitted."""
    out = []
    lay = model.layout
    names = rig.cable_names
    if lay.i_L is not None:
        out += [(f"cable {n} length", float(x), opts.length_std) for n, x in zip(names, gl.L - model.L0)]
    if lay.i_A is not None:
        for what, X in (("ceiling_anchor", gl.A - model.A), ("body_anchor", gl.B - model.b)):
            out += [(f"cable {n} {what} {a}", float(X[i, k]), opts.anchor_std)
                    for i, n in enumerate(names) for k, a in enumerate("xyz")]
    if lay.i_dd is not None:
        out += [(f"{labels[s]} dummy position {a}", float(gl.dd[s, k]), opts.dummy_position_std)
                for s in range(1, len(labels)) for k, a in enumerate("xyz")]
    return sorted(out, key=lambda t: -abs(t[1]) / t[2])


def _weakness(cc: np.ndarray, rig: Rig, solved, have_e: bool) -> dict:
    """The CG direction with the largest σ (eigenvector of the covariance), named."""
    ev, V = np.linalg.eigh(cc)
    d = V[:, -1] * np.sign(V[np.argmax(np.abs(V[:, -1])), -1])
    axis = "xyz"[int(np.argmax(np.abs(d)))]
    sd = np.sqrt(np.maximum(np.diag(cc), 0))
    R0, R1 = solved[0][0], solved[1][0]
    up0, up1 = R0.T @ Z, R1.T @ Z                 # the vertical in body axes, each state
    tilt = float(np.arctan2(np.linalg.norm(np.cross(up0, up1)), up0 @ up1))   # tilt change, rad
    # up direction of the baseline in body axes: the poorly determined direction is near it
    up_body = R0.T @ Z
    ang = float(np.degrees(np.arccos(min(1.0, abs(float(d @ up_body))))))
    text = (f"the CG {axis} coordinate is the least determined (σ {sd['xyz'.index(axis)] * 1e3:.2f} mm, "
            f"{math.sqrt(ev[-1]) / max(math.sqrt(max(ev[0], 0)), 1e-15):.0f}× the best direction): "
            f"the height along the vertical is found only through the {tilt * 1e3:.2f} mrad tilt change the "
            "dummy mass causes; a heavier dummy, farther out horizontally, or longer averaging reduce it")
    if ang > 30:
        text = (f"the CG is least determined along body direction [{d[0]:.2f}, {d[1]:.2f}, {d[2]:.2f}] "
                f"(σ {math.sqrt(ev[-1]) * 1e3:.2f} mm)")
    return {"axis": axis, "direction": [float(x) for x in d], "std": float(math.sqrt(ev[-1])),
            "angle_to_vertical_deg": ang, "tilt_change_rad": tilt, "text": text}
