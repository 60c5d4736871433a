"""The CG estimate of the static experiment: :func:`estimate_cg` (thesis section 2.2, eqs.
2.6–2.25, generalised; the method is described in :mod:`rig_identification.statics`).

The fit minimises the normalised misfit of what the rig measures in every state over the
global unknowns (scipy ``least_squares``, Jacobian by the implicit-function theorem through
:class:`~rig_identification.statics.model.StaticModel`), the rig's geometry fitted with its
survey σ as priors; it reports the covariance, the σ budget, the sensitivities and the model
validation, and rejects contradictory input with a
:class:`~rig_identification.statics.state.StaticsError`.

:func:`estimate_cg` runs these stages in order: the states and the streams they share
(:func:`_collect_states`), the input checks and a first pose per state (:func:`_initial_poses`),
the measured values (:func:`_measurements`), the start values (:func:`_start_values`), the
least-squares fit of the misfit (:class:`_Misfit`), the covariance (:func:`_fit_covariance`), the
σ split by source (:func:`_uncertainty`), the checks of the fitted states and geometry
(:func:`_fitted_poses`, :func:`_check_geometry`), the derived quantities (:func:`_load_cell_mass`,
:func:`_compliance`, :func:`_weakest_direction`) and the model validation (:func:`_validation`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
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
from .model import (
    DEFAULT_COMPLIANCE,
    CgOptions,
    EquationPartials,
    GlobalUnknowns,
    ParameterLayout,
    StaticModel,
    Z,
    skew,
)
from .result import CgResult, StatePose
from .state import StaticsError, StaticState
from .validation import CHI2_P_WARN, CgValidation, validate_fit

MASS_COVERAGE = 3.0              # mass disagreement warning: |Δ| > 3 σ combined
# contradictory geometry: the fit's χ² exceeds its dof by more than 20² (a 20 σ misfit, as the
# per-stream contradiction checks) and it needed an input moved by > 10 of its σ and > 5 mm
CONTRADICTION_CHI2 = 400.0
TOL_GEOMETRY = 5e-3              # m


# --- the values passed between the stages of the fit ----------------------------------------------

@dataclass(frozen=True)
class _States:
    """The static states of one fit and the streams they share.

    states (S,): the baseline first, then the dummy states; m_add (S,) kg and w_add (S,) of
    (3,) body kg m: the mass and first moment of the masses added in each state (0 in the
    baseline); have_T / have_e / have_a: the load cells / inclinometer / accelerometer enter
    the fit (every state has them and the options use them); tens (S,): per state (mean (N,) N,
    σ (N,) N) of the load cells in rig.yaml's cable order, or None without load cells."""

    states: list[StaticState]
    m_add: np.ndarray
    w_add: list[np.ndarray]
    have_T: bool
    have_e: bool
    have_a: bool
    tens: list

    @property
    def labels(self) -> list[str]:
        return [s.label for s in self.states]


@dataclass(frozen=True)
class _Measurements:
    """What the fit matches, per state s: meas[s] (k,) the measured values and sig[s] (k,) their
    σ (floored above 0), the streams used in :meth:`StaticModel.predict`'s order: the load
    cells (N,) N, the inclinometer elevations (2,) rad, the accelerometer (3,) m/s² (IMU axes)."""

    meas: list[np.ndarray]
    sig: list[np.ndarray]


@dataclass(frozen=True)
class _Start:
    """Start values of the fit: fixed, the globals in physical units (also the values of those
    not fitted, :meth:`StaticModel.unpack`); y0 (S,): per state (R (3, 3) body -> world, p (3,)
    world m, T (N,) N), the start of its equilibrium solve."""

    fixed: GlobalUnknowns
    y0: list[tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class _Evaluation:
    """The misfit at one θ: r (n_r,) normalised residuals (measurement rows state by state, then
    the prior rows); J (n_r, n_θ) ∂r/∂θ in the scaled θ of the :class:`ParameterLayout`; solved
    (S,): per state (R (3, 3) body -> world, p (3,) world m, T (N,) N, predicted (k,)) at its
    equilibrium; gl: the globals of θ; groups: (source, number of rows) in r's row order
    (``measurement_noise`` first, then the priors fitted)."""

    r: np.ndarray
    J: np.ndarray
    solved: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
    gl: GlobalUnknowns
    groups: list[tuple[str, int]]


@dataclass(frozen=True)
class _Covariance:
    """The covariance of a fit: U (n_r, n_θ), S (n_θ,), Vt (n_θ, n_θ): the SVD of the Jacobian
    with its columns divided by cn (n_θ,) (their norms, 1 for a zero column); cov (n_θ, n_θ)
    of θ in physical units (m, m/N, kg, 1, rad), times infl²; chi2, dof of the fit; infl: the σ
    inflation (1, or sqrt(χ²/dof) for an improbable χ² with ``inflate``); poor_fit: the
    warning for an improbable χ², or None."""

    U: np.ndarray
    S: np.ndarray
    Vt: np.ndarray
    cn: np.ndarray
    cov: np.ndarray
    chi2: float
    dof: int
    infl: float
    poor_fit: str | None


@dataclass(frozen=True)
class _Uncertainty:
    """The CG's σ split by source: sens, ∂CG/∂(rig.yaml value) of each systematic input (see
    :class:`CgResult`'s ``sensitivity``: (3, k) m per m, ``dummy_mass`` (3,) m/kg); budget, the σ
    (3,) m each row group contributes (inflated); std_noise (3,) m: the CG σ of the measurement
    noise alone (the systematic inputs exact at their fitted values, inflated)."""

    sens: dict[str, np.ndarray]
    budget: dict[str, np.ndarray]
    std_noise: np.ndarray


# --- before the fit: the states, their first poses, the measured values, the start values -----------

def _added(rig: Rig, st: StaticState, is_baseline: bool) -> tuple[DummyMass, ...]:
    """The masses added in the state ``st``: its own ``added``, else none in the baseline and
    rig.yaml's ``dummy_mass`` in a dummy state.  Raises :class:`StaticsError` for a dummy state
    without ``added`` when rig.yaml has no ``dummy_mass``."""
    if st.added is not None:
        return st.added
    if is_baseline:
        return ()
    if rig.dummy_mass is None:
        raise StaticsError(f"{rig.source}: the rig description has no dummy_mass (mass and position of "
                           "the dummy mass of the static experiment)")
    return (rig.dummy_mass,)


def _collect_states(rig: Rig, baseline: StaticState, dummy: StaticState | Sequence[StaticState],
                    opts: CgOptions) -> tuple[_States, list[str]]:
    """The states of the fit (baseline first), the masses added in each and the streams that
    enter the fit (:class:`_States`), with the warnings so far (the states' own, then one for an
    inclinometer missing in some state).  Raises :class:`StaticsError`: no dummy state, neither
    load cells nor an inclinometer, no dummy mass in any state, a cable without a load cell."""
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
    return _States(states, m_add, w_add, have_T, have_e, have_a, tens), warnings


def _initial_poses(rig: Rig, st: _States) -> tuple[list, list[float] | None, list[str]]:
    """The input checks and a first pose per state (rig.yaml's geometry): (poses (S,) of
    :class:`~rig_identification.estimation.tracker.StaticPose`, the vertical loads (S,) N the
    cables carry (None without load cells), warnings of a dummy load off its mass).  Raises
    :class:`StaticsError`: a slack cable, no pose that fits a state, a dummy state whose load
    grew by less than 0.3 of its added mass or whose inclination did not change."""
    warnings: list[str] = []
    if st.have_T:
        check_taut(rig, st.states, [t[0] for t in st.tens])
    poses = [initial_pose(rig, None if t is None else t[0], s.elevations if st.have_e else None, s.label)
             for s, t in zip(st.states, st.tens)]
    Wz = None
    if st.have_T:
        Wz = vertical_loads(rig, [t[0] for t in st.tens], poses)
        warnings += check_dummy_load(rig, st.states, Wz, st.m_add)
    check_tilt_change(st.states, poses, st.have_e)
    return poses, Wz, warnings


def _measurements(st: _States) -> _Measurements:
    """The measured values and their σ per state (:class:`_Measurements`), each σ floored: the
    load cells' at 1e-7 of the tension + 1e-9 N, the inclinometer's at 1e-9 rad, the
    accelerometer's at 1e-8 m/s²."""
    meas, sig = [], []
    for s, t in zip(st.states, st.tens):
        mv, sv = [], []
        if st.have_T:
            mv.append(t[0])
            sv.append(np.maximum(t[1], 1e-7 * np.abs(t[0]) + 1e-9))
        if st.have_e:
            e, e_sd = s.reading("inclinometer")
            mv.append(e)
            sv.append(np.maximum(e_sd, 1e-9))
        if st.have_a:
            f, f_sd = s.reading("accelerometer")
            mv.append(f)
            sv.append(np.maximum(f_sd, 1e-8))
        meas.append(np.concatenate(mv))
        sig.append(np.concatenate(sv))
    return _Measurements(meas, sig)


def _start_values(rig: Rig, model: StaticModel, st: _States, poses: list, Wz: list[float] | None) -> _Start:
    """Start values of the fit (:class:`_Start`): with load cells the mass from the baseline's
    vertical load Wz[0] N and the gain from the dummy states' extra load (when fitted), the CG
    (3,) body m from the moment balance linearised at the first poses (without load cells:
    rig.yaml's mass, gain 1 and the CG 1 m below the body anchors' centroid), the compliance
    known or :data:`~rig_identification.statics.model.DEFAULT_COMPLIANCE`, rig.yaml's lengths;
    each state's equilibrium solve starts at its first pose with the measured (or even)
    tensions."""
    lay = model.layout
    if Wz is not None:     # with load cells (st.have_T)
        m_lc0 = Wz[0] / rig.gravity
        kappa0 = 1.0
        if lay.i_k is not None:
            dm = [(Wd - Wz[0]) / rig.gravity for Wd in Wz[1:]]
            kappa0 = float(np.mean([md / d for md, d in zip(st.m_add[1:], dm) if d > 0]))
        m0 = kappa0 * m_lc0
    else:
        m0, kappa0 = rig.mass, 1.0
    comp0 = np.where(model.known, model.comp_known, DEFAULT_COMPLIANCE if lay.i_C is not None else 0.0)
    A, b = [], []
    for i, ps in enumerate(poses):
        R = ps.rotation.as_matrix()
        if st.have_T:
            rb = rig.body_anchors @ R.T
            v = rig.ceiling_anchors - ps.position - rb
            f = kappa0 * st.tens[i][0][:, None] * v / np.linalg.norm(v, axis=1)[:, None]
            Mc = np.cross(rb, f).sum(0) + np.cross(R @ st.w_add[i], model.gv)
            A.append(-m0 * skew(model.gv) @ R)
            b.append(-Mc)
    if A:
        c0 = np.linalg.lstsq(np.vstack(A), np.concatenate(b), rcond=None)[0]
    else:
        c0 = rig.body_anchors.mean(0) - np.array([0.0, 0.0, 1.0])
    n_s = len(st.states)
    fixed = GlobalUnknowns(c0, comp0, m0, kappa0, np.zeros(2), rig.cable_lengths.copy(),
                           np.zeros((n_s, 3)), np.zeros(n_s))
    y0 = []
    for i, ps in enumerate(poses):
        T0 = kappa0 * st.tens[i][0] if st.have_T else np.full(model.n, (m0 + st.m_add[i]) * rig.gravity / model.n)
        y0.append((ps.rotation.as_matrix(), ps.position.copy(), T0))
    return _Start(fixed, y0)


# --- the misfit and its Jacobian ------------------------------------------------------------------

def _input_slices(n_cables: int) -> dict[str, slice]:
    """Where each systematic input's rig.yaml value sits in the vector q of the sensitivities:
    the first dummy's position (3, body m) and mass (1, kg), the cable lengths (N, m), the
    ceiling anchors (3N, world m) and the body anchors (3N, body m), cable by cable, x y z.
    The length of q is the stop of ``body_anchors``."""
    n, n3 = n_cables, 3 * n_cables
    return {"dummy_position": slice(0, 3), "dummy_mass": slice(3, 4), "cable_lengths": slice(4, 4 + n),
            "ceiling_anchors": slice(4 + n, 4 + n + n3), "body_anchors": slice(4 + n + n3, 4 + n + 2 * n3)}


def _implicit(Fy: np.ndarray, F: np.ndarray) -> np.ndarray:
    """dy/dx = -Fy⁻¹ F of one state's equilibrium y (6 + N,) by the implicit-function theorem:
    Fy (N+6, 6+N) = ∂E/∂y, F (N+6, k) = ∂E/∂x; least squares when Fy is singular."""
    try:
        return -np.linalg.solve(Fy, F)
    except np.linalg.LinAlgError:
        return -np.linalg.lstsq(Fy, F, rcond=None)[0]


def _theta_partials(lay: ParameterLayout, part: EquationPartials, n_eq: int, i: int, ma: float,
                    dbar: np.ndarray, gl: GlobalUnknowns) -> np.ndarray:
    """∂E/∂θ (n_eq, n_θ), physical units, of state i's equations (n_eq = N + 6) from the partials
    ``part``: the CG, compliance, mass, lengths, anchors, and in a dummy state (i > 0) its
    dummy's position and mass offsets (ma kg its added mass, dbar (3,) body m the rig.yaml
    position of the added masses' centre)."""
    Fth = np.zeros((n_eq, lay.n))
    Fth[:, :3] = part.c
    if lay.i_C is not None:
        Fth[:, lay.i_C] = part.C
    Fth[:, lay.i_m] = part.m
    if lay.i_L is not None:
        Fth[:, lay.i_L] = part.L
    if i > 0 and lay.i_dd is not None:
        Fth[:, lay.i_dd[i - 1]] = part.w_add * ma
    if i > 0 and lay.i_dm is not None:
        Fth[:, lay.i_dm[i - 1]] = part.m_add + part.w_add @ (dbar + gl.offsets()[0][i])
    if lay.i_A is not None:
        Fth[:, lay.i_A] = part.A
        Fth[:, lay.i_B] = part.B
    return Fth


def _input_partials(part: EquationPartials, n_eq: int, i: int, ma: float, dbar: np.ndarray, gl: GlobalUnknowns,
                    q_slices: dict[str, slice]) -> np.ndarray:
    """∂E/∂q (n_eq, n_q) of state i's equations w.r.t. the systematic inputs' rig.yaml values q
    (:func:`_input_slices`): the first dummy's position and mass (state 1 only), the lengths and
    the anchors (ma kg, dbar (3,) body m as in :func:`_theta_partials`)."""
    Fq = np.zeros((n_eq, q_slices["body_anchors"].stop))
    if i == 1:
        Fq[:, 0:3] = part.w_add * ma
        Fq[:, 3] = part.m_add + part.w_add @ (dbar + gl.offsets()[0][i])
    Fq[:, q_slices["cable_lengths"]] = part.L
    Fq[:, q_slices["ceiling_anchors"]] = part.A
    Fq[:, q_slices["body_anchors"]] = part.B
    return Fq


def _prior(lay: ParameterLayout, idx, value: np.ndarray, std: float) -> tuple[np.ndarray, np.ndarray]:
    """One prior's rows: (residuals value / std (k,), their Jacobian (k, n_θ), 1 / std at the
    unknowns ``idx`` (k indices into θ)); value in the unknowns' physical units."""
    idx = np.ravel(idx)
    Jd = np.zeros((len(idx), lay.n))
    Jd[np.arange(len(idx)), idx] = 1.0 / std
    return np.ravel(value) / std, Jd


class _Misfit:
    """The fit's normalised misfit r(θ) and its Jacobian over the scaled θ of the model's
    :class:`ParameterLayout`: per state the measured values minus those predicted at its
    equilibrium for θ, over their σ (:class:`_Measurements`), then the priors (the scale's mass
    without load cells, the systematic inputs fitted with their survey σ).  Each state's
    equilibrium solve starts from the last one's (:class:`_Start` at first); the last
    :meth:`evaluate` is cached (``least_squares`` asks for r and J at the same θ).  Raises
    :class:`StaticsError` when a state has no equilibrium for θ."""

    def __init__(self, model: StaticModel, opts: CgOptions, st: _States, data: _Measurements, start: _Start,
                 scale_std: float):
        self.model, self.opts, self.st, self.data = model, opts, st, data
        self.fixed = start.fixed
        self.y_cache = list(start.y0)
        self.scale_std = scale_std
        self.q_slices = _input_slices(model.n)
        self._key: bytes | None = None
        self._last: _Evaluation | None = None

    def _state_rows(self, i: int, gl: GlobalUnknowns, consider: bool):
        """State i at the globals ``gl``: (r (k,), ∂r/∂θ (k, n_θ) physical, (R, p, T, predicted),
        with ``consider`` ∂r/∂q (k, n_q) of the systematic inputs' rig.yaml values, else None)."""
        lay, model, st = self.model.layout, self.model, self.st
        meas, sig = self.data.meas[i], self.data.sig[i]
        # the added masses, with the fitted offsets of the dummy's mass and position
        dd, dm = gl.offsets()
        ma = st.m_add[i] + dm[i]
        dbar = st.w_add[i] / st.m_add[i] if st.m_add[i] > 0 else np.zeros(3)
        wa = ma * (dbar + dd[i])
        R, p, T = model.solve_state(gl, ma, wa, self.y_cache[i], st.states[i].label)
        self.y_cache[i] = (R, p, T)
        E, Fy, part = model.equations(R, p, T, gl, ma, wa, jac=True)
        pred, Dy, Dk, Do = model.predict(R, T, gl)
        Jp = Dy @ _implicit(Fy, _theta_partials(lay, part, len(E), i, ma, dbar, gl))
        C = None
        if consider:   # the same through the equations, for the rig.yaml values q
            dq = _implicit(Fy, _input_partials(part, len(E), i, ma, dbar, gl, self.q_slices))
            C = -(Dy @ dq) / sig[:, None]
        if lay.i_k is not None:
            Jp[:, lay.i_k] += Dk
        if lay.i_off is not None:
            Jp[:, lay.i_off] += Do
        return (meas - pred) / sig, -Jp / sig[:, None], (R, p, T, pred), C

    def _priors(self, gl: GlobalUnknowns) -> tuple[list[np.ndarray], list[np.ndarray], list[tuple[str, int]]]:
        """The prior rows at ``gl``: (residuals, Jacobians (physical), (source, rows) each).  The
        scale's mass only without load cells (with them, the load cells weigh the body,
        calibrated by the dummy mass; the scale is then a cross-check); the systematic inputs
        fitted with their σ (offsets from rig.yaml's values)."""
        lay, model, opts = self.model.layout, self.model, self.opts
        pr, Jl, groups = [], [], []

        def add(name: str, idx, value: np.ndarray, std: float) -> None:
            r, Jd = _prior(lay, idx, value, std)
            pr.append(r)
            Jl.append(Jd)
            groups.append((name, len(np.ravel(idx))))

        if not self.st.have_T:
            add("scale", [lay.i_m], np.array([gl.m - model.rig.mass]), self.scale_std)
        if lay.i_L is not None:
            add("cable_lengths", lay.i_L, gl.L - model.L0, opts.length_std)
        if lay.i_dd is not None:
            add("dummy_position", lay.i_dd, gl.offsets()[0][1:], opts.dummy_position_std)
        if lay.i_dm is not None:
            add("dummy_mass", lay.i_dm, gl.offsets()[1][1:], opts.dummy_mass_std)
        if lay.i_A is not None:
            add("ceiling_anchors", lay.i_A, gl.A - model.A, opts.anchor_std)
            add("body_anchors", lay.i_B, gl.B - model.b, opts.anchor_std)
        return pr, Jl, groups

    def evaluate(self, th: np.ndarray) -> _Evaluation:
        """The misfit at the scaled θ (n_θ,) (:class:`_Evaluation`, J in scaled θ); the same
        object again for the θ of the last call."""
        key = th.tobytes()
        if key == self._key and self._last is not None:
            return self._last
        gl = self.model.unpack(th, self.fixed)
        rows = [self._state_rows(i, gl, False) for i in range(len(self.st.states))]
        pr, Jl, prior_groups = self._priors(gl)
        groups = [("measurement_noise", sum(len(x[0]) for x in rows))] + prior_groups
        r = np.concatenate([x[0] for x in rows] + pr)
        J = np.vstack([x[1] for x in rows] + Jl) * self.model.layout.scale_arr[None, :]
        self._key, self._last = key, _Evaluation(r, J, [x[2] for x in rows], gl, groups)
        return self._last

    def input_jacobian(self, th: np.ndarray) -> np.ndarray:
        """∂r/∂q (n_r, n_q) at the scaled θ: the residuals' change per unit change of the
        systematic inputs' rig.yaml values q (:func:`_input_slices`; zero in the prior rows)."""
        gl = self.model.unpack(th, self.fixed)
        C_all = [self._state_rows(i, gl, True)[3] for i in range(len(self.st.states))]
        n_prior = sum(len(x) for x in self._priors(gl)[0])
        return np.vstack(C_all + [np.zeros((n_prior, self.q_slices["body_anchors"].stop))])


# --- after the fit: covariance, σ split, checks of the fitted states and geometry ------------------

def _fit_covariance(ev: _Evaluation, lay: ParameterLayout, inflate: bool) -> _Covariance:
    """The covariance (JᵀJ)⁻¹ of θ at the solution ``ev`` (column-scaled for conditioning), the
    fit's χ² and dof, and the σ inflation and warning of an improbable χ² (p <
    :data:`~rig_identification.statics.validation.CHI2_P_WARN`; inflated only with ``inflate``).
    Raises :class:`StaticsError` when the states do not determine θ (singular Jacobian: the
    message names the two unknowns of the null direction)."""
    r, J = ev.r, ev.J
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
            if inflate:
                infl = math.sqrt(chi2 / dof)
            poor_fit = (f"the data fit the static model poorly (χ² = {chi2:.1f} for {dof} degrees of "
                        f"freedom, p = {pval:.1e})" + (f"; σ inflated ×{infl:.2f}" if infl > 1 else ""))
    cov = cov * infl**2
    return _Covariance(U, S, Vt, cn, cov, chi2, dof, infl, poor_fit)


def _uncertainty(misfit: _Misfit, th: np.ndarray, ev: _Evaluation, fc: _Covariance) -> _Uncertainty:
    """The CG's σ split by source at the solution θ (scaled, n_θ) (:class:`_Uncertainty`): the
    estimator's gain G = (JᵀJ)⁻¹Jᵀ (CG rows, physical units: δc = -G δr) gives the
    sensitivities to the systematic inputs' rig.yaml values, δc = -G (∂r/∂q) δq (fitted or not),
    and the budget, G Gᵀ split by the rows' sources (they add up to the covariance); the
    noise-only σ is that of the Jacobian restricted to the measurement (and scale) rows and the
    unknowns that are not systematic inputs.  Raises :class:`StaticsError` as
    :meth:`_Misfit.input_jacobian`."""
    lay = misfit.model.layout
    U, S, Vt, cn, infl = fc.U, fc.S, fc.Vt, fc.cn, fc.infl
    G = ((Vt.T / S) @ U.T)[:3] / cn[:3, None] * lay.scale_arr[:3, None]
    Sq = -G @ misfit.input_jacobian(th)
    sens = {k: (Sq[:, sl] if k != "dummy_mass" else Sq[:, sl][:, 0]) for k, sl in misfit.q_slices.items()}
    budget, k0 = {}, 0
    for name, nrows in ev.groups:
        g = G[:, k0:k0 + nrows]
        budget[name] = infl * np.sqrt(np.sum(g**2, axis=1))
        k0 += nrows
    groups = ev.groups
    rows = np.r_[0:groups[0][1]]
    if not misfit.st.have_T:
        rows = np.r_[rows, groups[0][1]]
    Jn = ev.J[np.ix_(rows, lay.core)]
    cnn = np.linalg.norm(Jn, axis=0)
    cnn[cnn == 0] = 1.0
    _, Sn, Vnt = np.linalg.svd(Jn / cnn, full_matrices=False)
    cov_n = (Vnt.T / Sn**2) @ Vnt / np.outer(cnn, cnn) * np.outer(lay.scale_arr[lay.core], lay.scale_arr[lay.core])
    return _Uncertainty(sens, budget, infl * np.sqrt(np.diag(cov_n)[:3]))


def _stream_names(st: _States) -> list[str]:
    """The streams that enter the fit, in the measurement vector's order."""
    return (["load_cells"] if st.have_T else []) + (["inclinometer"] if st.have_e else []) \
        + (["accelerometer"] if st.have_a else [])


def _fitted_poses(rig: Rig, model: StaticModel, st: _States, data: _Measurements, ev: _Evaluation,
                  stream_names: list[str]) -> list[StatePose]:
    """The fitted equilibrium of each state (:class:`StatePose`, world frame, tensions N) with
    its streams' misfits.  Raises :class:`StaticsError`: a cable slack at a fitted equilibrium
    (below :data:`~rig_identification.statics.checks.SLACK_FRACTION` of an even share of the
    weight), a stream misfit of > 20 σ beyond its tolerance (contradictory geometry or data)."""
    poses_out = []
    for i, (s, (R, p, T, pred)) in enumerate(zip(st.states, ev.solved)):
        if T.min() < SLACK_FRACTION * (ev.gl.m + st.m_add[i]) * rig.gravity / model.n:
            j = int(np.argmin(T))
            raise StaticsError(f"{s.label}: cable {rig.cable_names[j]} would be slack at the fitted equilibrium "
                               f"(tension {T[j]:.1f} N): contradictory geometry or data")
        res = stream_misfits(s.label, rig, stream_names, data.meas[i], pred, data.sig[i])
        poses_out.append(StatePose(s.label, p, R, T, float(st.m_add[i]), s.window, res))
    return poses_out


def _check_geometry(rig: Rig, model: StaticModel, opts: CgOptions, gl: GlobalUnknowns, labels: list[str],
                    fc: _Covariance) -> None:
    """Raises :class:`StaticsError` when the data need a systematic input moved far beyond its
    σ: χ² > dof + :data:`CONTRADICTION_CHI2` and the input most moved (over its σ) changed by
    > 10 σ and > :data:`TOL_GEOMETRY` m (contradictory rig.yaml; the message names the three
    most moved)."""
    chi2, dof = fc.chi2, fc.dof
    dev = _input_deviations(gl, model, opts, rig, labels)
    if (dev and chi2 > dof + CONTRADICTION_CHI2 and abs(dev[0][1]) > 10 * dev[0][2]
            and abs(dev[0][1]) > TOL_GEOMETRY):
        top = "; ".join(f"{nm} {d * 1e3:+.1f} mm (σ {sd * 1e3:g} mm)" for nm, d, sd in dev[:3])
        raise StaticsError(f"the static states contradict rig.yaml's geometry: the best fit (χ² = {chi2:.0f} for "
                           f"{dof} degrees of freedom) needs {top} from rig.yaml's values: contradictory geometry or "
                           "data "
                           "(check rig.yaml's anchors, cable lengths and dummy_mass; or give their real σ with "
                           "--anchor-std, --length-std, --dummy-position-std)")


# --- derived quantities -------------------------------------------------------------------------

def _load_cell_mass(rig: Rig, st: _States, pose0, scale_std: float, gl: GlobalUnknowns,
                    fc: _Covariance, lay: ParameterLayout) -> tuple[float | None, float | None, list[str]]:
    """The body's mass kg the load cells imply and its σ kg (None, None without load cells):
    the baseline's vertical tension components / g at its first pose ``pose0`` with rig.yaml's
    geometry (independent of the CG fit, whose fitted anchors would trade the weight for the
    geometry), with a warning when it and the scale's reading (σ ``scale_std`` kg) disagree
    by more than :data:`MASS_COVERAGE` combined σ."""
    if not st.have_T:
        return None, None, []
    t0 = st.tens[0]
    v = rig.ceiling_anchors - (pose0.position + pose0.rotation.apply(rig.body_anchors))
    uz = v[:, 2] / np.linalg.norm(v, axis=1)
    m_lc = float(t0[0] @ uz / rig.gravity)
    m_lc_sd = float(np.sqrt(np.sum((t0[1] * uz) ** 2)) / rig.gravity)
    comb = math.hypot(m_lc_sd, scale_std)
    if abs(m_lc - rig.mass) <= MASS_COVERAGE * comb:
        return m_lc, m_lc_sd, []
    cal = ""
    if lay.i_k is not None:
        cal = (f"; calibrated by the dummy mass (gain {gl.kappa:.5f}) they weigh "
               f"{gl.m:.2f} ± {math.sqrt(fc.cov[lay.i_m, lay.i_m]):.2f} kg")
    return m_lc, m_lc_sd, [f"mass: the load cells imply {m_lc:.2f} ± {m_lc_sd:.2f} kg, the scale read "
                           f"{rig.mass:.2f} kg (assumed σ {scale_std:.2f} kg): they disagree by "
                           f"{abs(m_lc - rig.mass) / comb:.1f} σ (> {MASS_COVERAGE:g} σ){cal}"]


def _compliance(model: StaticModel, gl: GlobalUnknowns, cov: np.ndarray) -> tuple[tuple, list[str]]:
    """The fitted common compliance of the cables without a stiffness in rig.yaml: ((C m/N, its
    σ, the stiffness 1/C N/m and its σ), warnings); each None when not fitted, the stiffness
    None unless C > 3 σ; a warning when C < -3 σ (cables that shorten under load)."""
    lay = model.layout
    if lay.i_C is None:
        return (None, None, None, None), []
    k_fit = k_sd = None
    C = float(gl.comp[~model.known].mean())
    C_sd = float(math.sqrt(cov[lay.i_C, lay.i_C]))
    if C > 3 * C_sd:
        k_fit, k_sd = 1.0 / C, C_sd / C**2
    warnings = []
    if C < -3 * C_sd:
        warnings.append(f"the fitted cable compliance is negative ({C:.2e} ± {C_sd:.1e} m/N): the cables "
                        "seem to shorten under load; check the cable lengths")
    return (C, C_sd, k_fit, k_sd), warnings


def _weakest_direction(cc: np.ndarray, rig: Rig, solved: list, have_e: bool, budget: dict[str, np.ndarray]) -> dict:
    """:func:`_weakness` of the CG covariance cc (3, 3) m² with ``systematic_share``, the part of
    its axis's variance the systematic inputs make (σ budget); above 0.5 the text says a better
    survey, not longer averaging, reduces it."""
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
    return weak


def _mass_check(rig: Rig, m_lc: float | None, m_lc_sd: float | None, scale_std: float) -> Check | None:
    """The load cells' weight m_lc ± m_lc_sd kg against the scale's (σ ``scale_std`` kg) as a
    :class:`~rig_identification.io.verdict.Check` (passed within :data:`MASS_COVERAGE` combined
    σ), or None without load cells."""
    if m_lc is None or m_lc_sd is None:
        return None
    comb = math.hypot(m_lc_sd, scale_std)
    z = abs(m_lc - rig.mass) / comb
    return Check("mass", z, MASS_COVERAGE, bool(z <= MASS_COVERAGE),
                 f"load cells {m_lc:.2f} ± {m_lc_sd:.2f} kg against the scale's {rig.mass:.2f} ± "
                 f"{scale_std:.2f} kg: {z:.1f} σ (a cross-check: the CG fit uses the load cells "
                 "calibrated by the dummy mass)")


def _validation(model: StaticModel, st: _States, data: _Measurements, ev: _Evaluation, fc: _Covariance,
                mass_check: Check | None, opts: CgOptions) -> CgValidation:
    """The :class:`CgValidation` of the fit (:func:`~.validation.validate_fit`): the residuals
    with the left singular vectors U of the Jacobian, the inclinometer's rows per state (x row,
    y row, their σ (2,) rad; none without it), χ², dof and the mass check."""
    incl_rows = []
    if st.have_e:
        k0 = 0
        o = model.n if st.have_T else 0
        for i in range(len(st.states)):
            incl_rows.append((k0 + o, k0 + o + 1, data.sig[i][o:o + 2]))
            k0 += len(data.meas[i])
    return validate_fit(ev.r, fc.U, incl_rows, st.labels, fc.chi2, int(fc.dof), mass_check,
                        opts.fit_inclinometer_offset)


def _validation_warnings(warnings: list[str], validation: CgValidation, poor_fit: str | None,
                         opts: CgOptions) -> list[str]:
    """``warnings`` with the poor-fit warning ``poor_fit`` (when in it) completed by its likely
    cause -- the failed ``tilt_change`` / ``inclinometer_level`` checks, else a geometry less
    certain than the σ assumed -- and a warning per such failed check appended."""
    out = list(warnings)
    named = [ck for ck in validation.checks if ck.passed is False and ck.name in ("tilt_change", "inclinometer_level")]
    if poor_fit is not None:
        hint = ("; see the failed check(s) " + ", ".join(ck.name for ck in named) if named else
                f"; if rig.yaml's geometry is less certain than the σ assumed (anchors {opts.anchor_std * 1e3:g} mm, "
                f"cable lengths {opts.length_std * 1e3:g} mm, dummy position {opts.dummy_position_std * 1e3:g} mm), "
                "give larger ones (--anchor-std, --length-std, --dummy-position-std)")
        out[out.index(poor_fit)] = poor_fit + hint
    for ck in named:
        out.append(f"model validation: check {ck.name} failed: {ck.detail}")
    return out


# --- the estimator --------------------------------------------------------------------------------

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
    st, warnings = _collect_states(rig, baseline, dummy, opts)
    poses, Wz, load_warnings = _initial_poses(rig, st)
    warnings += load_warnings
    model = StaticModel(rig, opts, st.have_T, st.have_e, st.have_a, len(st.states))
    lay = model.layout
    data = _measurements(st)
    scale_std = opts.scale_std if opts.scale_std is not None else rig.survey.mass_std(rig.mass)
    misfit = _Misfit(model, opts, st, data, _start_values(rig, model, st, poses, Wz), scale_std)

    th0 = model.pack(misfit.fixed)
    rows = len(misfit.evaluate(th0).r)
    if rows < len(th0):
        raise StaticsError(f"{rows} measurements for {len(th0)} unknowns: the streams used and the priors do not "
                           "determine the fit (use the load cells, or give the geometry a survey σ, or fit fewer "
                           "offsets)")
    sol = least_squares(lambda th: misfit.evaluate(th).r, th0, jac=lambda th: misfit.evaluate(th).J, method="lm",
                        x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
    ev = misfit.evaluate(sol.x)
    fc = _fit_covariance(ev, lay, opts.inflate)
    if fc.poor_fit is not None:
        warnings.append(fc.poor_fit)
    unc = _uncertainty(misfit, sol.x, ev, fc)

    # --- contradiction checks in physical units: slack in the fitted model, moved geometry
    stream_names = _stream_names(st)
    poses_out = _fitted_poses(rig, model, st, data, ev, stream_names)
    gl = ev.gl
    _check_geometry(rig, model, opts, gl, st.labels, fc)
    cc = fc.cov[:3, :3]
    c_std = np.sqrt(np.diag(cc))
    m_lc, m_lc_sd, mass_warnings = _load_cell_mass(rig, st, poses[0], scale_std, gl, fc, lay)
    warnings += mass_warnings
    m_sd = float(math.sqrt(fc.cov[lay.i_m, lay.i_m]))
    kap = kap_sd = None
    if lay.i_k is not None:
        kap, kap_sd = float(gl.kappa), float(math.sqrt(fc.cov[lay.i_k, lay.i_k]))
    (C, C_sd, k_fit, k_sd), comp_warnings = _compliance(model, gl, fc.cov)
    warnings += comp_warnings
    off = gl.off.copy() if lay.i_off is not None else None
    weak = _weakest_direction(cc, rig, ev.solved, st.have_e, unc.budget)
    validation = _validation(model, st, data, ev, fc, _mass_check(rig, m_lc, m_lc_sd, scale_std), opts)
    warnings = _validation_warnings(warnings, validation, fc.poor_fit, opts)
    return CgResult(gl.c.copy(), c_std, cc, float(rig.mass), float(scale_std), m_lc, m_lc_sd, float(gl.m), m_sd,
                    kap, kap_sd, k_fit, k_sd, C, C_sd, off, poses_out, fc.chi2, int(fc.dof), fc.infl, weak, warnings,
                    list(lay.names), fc.cov, stream_names, unc.sens, center_of_gravity_std_noise=unc.std_noise,
                    geometry_std=opts.geometry_std(), budget=unc.budget, validation=validation)


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
        dd = gl.offsets()[0]
        out += [(f"{labels[s]} dummy position {a}", float(dd[s, k]), opts.dummy_position_std)
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
