"""The mechanical model of the static experiment (thesis chapter 2, section 2.2, generalised).

State s of the suspended body is at rest in the pose (R_s, p_s) (rotation body -> world, world
position of the body-frame origin) with cable tensions T_s (N,); for the global unknowns θ
(:class:`GlobalUnknowns`) it solves the N + 6 equations of cable length (thesis eqs.
2.13–2.19, stretched), force balance (eqs. 2.20–2.22) and moment balance about the body origin
(eqs. 2.23–2.25, with the dummy mass's term of section 2.2.3) -- see
:mod:`rig_identification.statics`.  :class:`StaticModel` holds the rig's geometry and sensor
layout, evaluates the equations with their analytic Jacobian, solves one state's equilibrium
(Newton) and predicts what the rig measures in it (load cells, inclinometer elevations,
accelerometer).  :class:`CgOptions` says what a fit uses and assumes, with the survey σ of the
rig's geometry (:data:`DEFAULT_ANCHOR_STD` ...).  :func:`static_equilibrium` is the forward
model: the equilibrium of a body of known mass and CG.

Frames and units: world z up, gravity (0, 0, -g); body frame fixed to the carrying frame; SI
units (m, kg, N, rad, s).  Errors: :class:`~rig_identification.statics.state.StaticsError`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np
from scipy.linalg import expm

from ..io.rig import DummyMass, Rig, Survey
from ..model.cables import CableModel
from ..model.equilibrium import equilibrium
from ..model.rigid_body import SimulationError, skew, skews
from .state import StaticsError

Z = np.array([0.0, 0.0, 1.0])    # world z, up (gravity is -g Z)
DEFAULT_COMPLIANCE = 2e-7        # m/N: a steel cable of a few metres (k = 5e6 N/m), start value
# The rig's geometry as surveyed, 1 σ per coordinate, when rig.yaml's ``survey`` does not say
# (:class:`~rig_identification.io.rig.Survey`; rig-identify cg --anchor-std/--length-std/
# --dummy-position-std override it for one run).  On the reference static pair
# (visible_case16_static) these 1 mm make the CG height's σ 22× the noise's (9.4 mm against
# 0.43 mm; docs/cg.md).
DEFAULT_ANCHOR_STD = Survey.anchors        # m: every ceiling anchor (world) and body anchor (body) coordinate
DEFAULT_LENGTH_STD = Survey.lengths        # m: every unstretched cable length
DEFAULT_DUMMY_POSITION_STD = Survey.dummy_position  # m: every coordinate of the dummy mass's centre of gravity


@dataclass(frozen=True)
class CgOptions:
    """What the fit uses and assumes.

    use_load_cells / use_inclinometer / use_accelerometer: which streams enter the misfit
    (the accelerometer is off by default: its bias is not modelled and a 1 mg bias is a
    1 mrad tilt).  fit_compliance: fit one common cable compliance for the cables without a
    stiffness in rig.yaml (``None`` = when load cells are used; else those cables are
    inextensible, as in the thesis).  fit_load_cell_gain: fit one common load-cell gain
    (needs load cells; it makes the CG independent of a load-cell calibration error).
    fit_inclinometer_offset: fit the inclinometer's two zero offsets.
    scale_std: σ of the scale's mass reading, kg (default 0.1 % of it).
    The rig's geometry as surveyed (1 σ; 0 = taken as exact; > 0 fits the input with that
    prior, which propagates its uncertainty into the CG σ -- ``center_of_gravity_std``; the
    σ of the measurement noise alone is ``center_of_gravity_std_noise``): anchor_std: each
    coordinate of every ceiling anchor (world) and body anchor (body), m; length_std: the
    rig.yaml cable lengths, m; dummy_position_std: each coordinate of the dummy mass's
    position, m (its horizontal position matters most for the CG height); defaults
    :data:`DEFAULT_ANCHOR_STD`, :data:`DEFAULT_LENGTH_STD`, :data:`DEFAULT_DUMMY_POSITION_STD`
    (1 mm, a steel-tape survey).  dummy_mass_std: σ of the dummy mass, kg (default 0: weighed
    exactly).  inflate: multiply σ by sqrt(χ²/dof) when the fit's χ² is improbable (p < 0.01).
    """

    use_load_cells: bool = True
    use_inclinometer: bool = True
    use_accelerometer: bool = False
    fit_compliance: bool | None = None
    fit_load_cell_gain: bool = True
    fit_inclinometer_offset: bool = False
    scale_std: float | None = None
    length_std: float = DEFAULT_LENGTH_STD
    dummy_position_std: float = DEFAULT_DUMMY_POSITION_STD
    dummy_mass_std: float = 0.0
    anchor_std: float = DEFAULT_ANCHOR_STD
    inflate: bool = True

    @classmethod
    def from_survey(cls, survey: Survey, **kw) -> "CgOptions":
        """Options whose geometry σ and scale σ are rig.yaml's ``survey`` (``kw`` overrides)."""
        return cls(**{"length_std": survey.lengths, "dummy_position_std": survey.dummy_position,
                      "anchor_std": survey.anchors, "scale_std": survey.mass, **kw})

    @classmethod
    def exact_geometry(cls, **kw) -> "CgOptions":
        """Options that take the rig's geometry and the dummy mass as exact (noise-only σ)."""
        return cls(**{"length_std": 0.0, "dummy_position_std": 0.0, "anchor_std": 0.0, **kw})

    def geometry_std(self) -> dict[str, float]:
        """The σ assumed for the systematic inputs (m, dummy_mass kg), by name."""
        return {"anchors": float(self.anchor_std), "cable_lengths": float(self.length_std),
                "dummy_position": float(self.dummy_position_std), "dummy_mass": float(self.dummy_mass_std)}


@dataclass(frozen=True)
class FittedGlobals:
    """Which global unknowns the static fit frees besides the CG and the mass (each fixed at its
    rig.yaml value where False): the cables' compliance, a common load-cell gain, the
    inclinometer's offsets, the cable lengths, each dummy's position and mass, the anchors."""

    compliance: bool
    load_cell_gain: bool
    inclinometer_offset: bool
    lengths: bool
    dummy_position: bool = False
    dummy_mass: bool = False
    anchors: bool = False


class ParameterLayout:
    """Indices of the global unknowns θ (internal scaled units) and their scales.

    ``names`` (n,): the unknowns in θ's order -- ``cg_x``, ``cg_y``, ``cg_z``, then those
    fitted: ``compliance``, ``mass``, ``load_cell_gain``, ``incl_offset_x``/``_y``,
    ``length_<i>``, ``dummy<s>_<x|y|z>``, ``dummy<s>_mass``, ``ceiling_anchor_<i>_<x|y|z>``,
    ``body_anchor_<i>_<x|y|z>``; ``scale`` (list) / ``scale_arr`` (n,): a physical value
    (offset) is θ · scale (m, m/N, kg, 1, rad); ``i_C``, ``i_m``, ``i_k`` (int, or None) and
    ``i_off``, ``i_L``, ``i_dd``, ``i_dm``, ``i_A``, ``i_B`` (index lists, or None): where each
    unknown sits in θ, None when it is not fitted; ``core``: the indices of the unknowns that
    are not systematic inputs (lengths, dummy, anchors) -- those of the noise-only σ.
    """

    def __init__(self, n_cables: int, fitted: FittedGlobals, n_states: int = 2):
        self.names: list[str] = ["cg_x", "cg_y", "cg_z"]
        self.scale: list[float] = [1.0, 1.0, 1.0]
        self.fitted = fitted
        self.i_C = self._add("compliance", 1e-7) if fitted.compliance else None
        self.i_m = self._add("mass", 1.0)
        self.i_k = self._add("load_cell_gain", 1e-3) if fitted.load_cell_gain else None
        self.i_off = [self._add(f"incl_offset_{a}", 1e-3) for a in "xy"] if fitted.inclinometer_offset else None
        self.i_L = [self._add(f"length_{i}", 1e-3) for i in range(n_cables)] if fitted.lengths else None
        # per dummy state (1 .. n_states-1): position offset (3) and mass offset of its dummy
        self.i_dd = [[self._add(f"dummy{s}_{a}", 1e-3) for a in "xyz"] for s in range(1, n_states)] \
            if fitted.dummy_position else None
        self.i_dm = [self._add(f"dummy{s}_mass", 1.0) for s in range(1, n_states)] if fitted.dummy_mass else None
        # anchors: (N, 3) row-major, ceiling (world) then body (body frame)
        self.i_A = [self._add(f"ceiling_anchor_{i}_{a}", 1e-3) for i in range(n_cables) for a in "xyz"] \
            if fitted.anchors else None
        self.i_B = [self._add(f"body_anchor_{i}_{a}", 1e-3) for i in range(n_cables) for a in "xyz"] \
            if fitted.anchors else None
        self.core = [i for i, nm in enumerate(self.names)
                     if not nm.startswith(("length_", "dummy", "ceiling_anchor_", "body_anchor_"))]
        self.scale_arr = np.array(self.scale)

    def _add(self, name: str, scale: float) -> int:
        self.names.append(name)
        self.scale.append(scale)
        return len(self.names) - 1

    @property
    def n(self) -> int:
        return len(self.names)


@dataclass(frozen=True)
class GlobalUnknowns:
    """The global unknowns θ of the fit in physical units (common to every static state).

    c (3,) body m: the CG of the suspended body; comp (N,) m/N: compliance of each cable
    (0 = inextensible); m kg: the suspended mass; kappa (1): the load-cell gain (true tension =
    κ · reading); off (2,) rad: the inclinometer's zero offsets (x, y); L (N,) m: the unstretched
    cable lengths; optional dd (S, 3) body m and dm (S,) kg: the offsets of each state's dummy
    position and mass from rig.yaml's (row 0, the baseline, unused; None: zero), A (N, 3) world m
    and B (N, 3) body m: the ceiling and body anchors (None: rig.yaml's).  Cable order: rig.yaml's.
    :meth:`StaticModel.unpack` and :meth:`StaticModel.pack` convert from and to the scaled θ.
    """

    c: np.ndarray           # (3,) body m
    comp: np.ndarray        # (N,) compliance per cable, m/N
    m: float
    kappa: float
    off: np.ndarray         # (2,) rad
    L: np.ndarray           # (N,) m
    dd: np.ndarray | None = None   # (S, 3) m: dummy position offsets per state (row 0 unused)
    dm: np.ndarray | None = None   # (S,) kg: dummy mass offsets per state
    A: np.ndarray | None = None    # (N, 3) world m: ceiling anchors (None: rig.yaml's)
    B: np.ndarray | None = None    # (N, 3) body m: body anchors (None: rig.yaml's)

    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """(dd (S, 3), dm (S,)): the dummy offsets, as :meth:`StaticModel.unpack` sets them.  Raises
        :class:`StaticsError` when they are not set."""
        if self.dd is None or self.dm is None:
            raise StaticsError("the global unknowns carry no dummy offsets dd, dm (StaticModel.unpack sets them)")
        return self.dd, self.dm


class EquationPartials(NamedTuple):
    """Derivatives of one state's scaled equilibrium equations E (N + 6,) w.r.t. the globals:
    c (N+6, 3), common compliance C (N+6,), mass m (N+6,), lengths L (N+6, N), added mass
    (N+6,), added first moment w (N+6, 3) body frame, ceiling anchors A (N+6, 3N) and body
    anchors B (N+6, 3N) (row-major (N, 3))."""

    c: np.ndarray
    C: np.ndarray
    m: np.ndarray
    L: np.ndarray
    m_add: np.ndarray
    w_add: np.ndarray
    A: np.ndarray
    B: np.ndarray


class StaticModel:
    """Geometry and sensor layout of the rig; per-state equilibrium solve.

    rig: the rig description (anchors, cable lengths and stiffness, inclinometer and IMU
    mounting, gravity); opts: the :class:`CgOptions` (which unknowns are fitted: ``layout``, a
    :class:`ParameterLayout`); tensions_used, incl_used, accel_used: which streams are predicted
    (:meth:`predict`); n_states: the number of states (baseline + dummy states).  The
    equilibrium equations (:meth:`equations`) are those of the package docstring (thesis eqs.
    2.13–2.25 with stretched cables, N >= 3); :meth:`solve_state` solves them for one state.
    """

    def __init__(self, rig: Rig, opts: CgOptions, tensions_used: bool, incl_used: bool, accel_used: bool,
                 n_states: int = 2):
        self.rig = rig
        self.A = rig.ceiling_anchors
        self.b = rig.body_anchors
        self.L0 = rig.cable_lengths
        k = rig.cable_stiffness
        self.known = np.isfinite(k)
        self.comp_known = np.where(self.known, 1.0 / np.where(self.known, k, 1.0), 0.0)
        self.n = len(self.L0)
        self.g = rig.gravity
        self.gv = np.array([0.0, 0.0, -rig.gravity])
        self.incl = rig.inclinometer.rotation.as_matrix() if (incl_used and rig.inclinometer is not None) else None
        self.imu = rig.imu.rotation.as_matrix()
        self.tensions_used, self.accel_used = tensions_used, accel_used
        fit_c = opts.fit_compliance
        if fit_c is None:
            fit_c = tensions_used
        fit_c = bool(fit_c) and not self.known.all()
        self.n_states = n_states
        fitted = FittedGlobals(fit_c, bool(opts.fit_load_cell_gain and tensions_used),
                               bool(opts.fit_inclinometer_offset and self.incl is not None), opts.length_std > 0,
                               opts.dummy_position_std > 0, opts.dummy_mass_std > 0, opts.anchor_std > 0)
        self.layout = ParameterLayout(self.n, fitted, n_states)

    # θ (internal) <-> physical
    def unpack(self, th: np.ndarray, fixed: GlobalUnknowns) -> GlobalUnknowns:
        """The globals of the scaled θ (layout.n,); those not fitted are taken from ``fixed``."""
        lay = self.layout
        x = th * lay.scale_arr
        comp = fixed.comp.copy()
        if lay.i_C is not None:
            comp = np.where(self.known, self.comp_known, x[lay.i_C])
        kappa = 1.0 + x[lay.i_k] if lay.i_k is not None else fixed.kappa
        off = x[lay.i_off] if lay.i_off is not None else fixed.off
        L = x[lay.i_L] + self.L0 if lay.i_L is not None else fixed.L
        dd = np.zeros((self.n_states, 3))
        dm = np.zeros(self.n_states)
        if lay.i_dd is not None:
            dd[1:] = x[np.array(lay.i_dd)]
        if lay.i_dm is not None:
            dm[1:] = x[lay.i_dm]
        A = x[lay.i_A].reshape(-1, 3) + self.A if lay.i_A is not None else fixed.A
        B = x[lay.i_B].reshape(-1, 3) + self.b if lay.i_B is not None else fixed.B
        return GlobalUnknowns(x[:3].copy(), comp, x[lay.i_m], kappa, np.asarray(off, float), np.asarray(L, float),
                              dd, dm, A, B)

    def pack(self, g: GlobalUnknowns) -> np.ndarray:
        """The scaled θ (layout.n,) of the globals ``g`` (the inverse of :meth:`unpack`)."""
        lay = self.layout
        x = np.zeros(lay.n)
        x[:3] = g.c
        if lay.i_C is not None:
            x[lay.i_C] = g.comp[~self.known].mean()
        x[lay.i_m] = g.m
        if lay.i_k is not None:
            x[lay.i_k] = g.kappa - 1.0
        if lay.i_off is not None:
            x[lay.i_off] = g.off
        if lay.i_L is not None:
            x[lay.i_L] = g.L - self.L0
        if lay.i_dd is not None and g.dd is not None:
            x[np.array(lay.i_dd)] = g.dd[1:]
        if lay.i_dm is not None and g.dm is not None:
            x[lay.i_dm] = g.dm[1:]
        if lay.i_A is not None and g.A is not None:
            x[lay.i_A] = (g.A - self.A).ravel()
        if lay.i_B is not None and g.B is not None:
            x[lay.i_B] = (g.B - self.b).ravel()
        return x / lay.scale_arr

    # --- equilibrium equations of one state (scaled: lengths m, forces / W, moments / W m)
    def equations(self, R, p, T, gl: GlobalUnknowns, m_add: float, w_add: np.ndarray, jac: bool = False):
        """Scaled equilibrium equations E (N + 6,) of one state (package docstring; thesis eqs.
        2.13–2.25): length (m), force (/ W) and moment (/ W m) balance, W the weight of the body
        and the added masses.  R (3, 3) body -> world, p (3,) world m, T (N,) N: the state's
        pose and tensions; m_add kg and w_add (3,) body kg m: the mass and first moment of the
        masses added in the state.  With ``jac``: (E, ∂E/∂y (N+6, 6+N) for y = (δφ, p, T),
        δφ (3,) rad the rotation vector of a world-frame rotation R -> exp([δφ]×) R,
        :class:`EquationPartials`)."""
        W = (gl.m + m_add) * self.g
        A = self.A if gl.A is None else gl.A
        bb = self.b if gl.B is None else gl.B
        rb = bb @ R.T
        v = A - p - rb
        l = np.linalg.norm(v, axis=1)
        u = v / l[:, None]
        f = T[:, None] * u
        w = gl.m * gl.c + w_add
        Rw = R @ w
        e_len = l - gl.L - gl.comp * T
        F = f.sum(0) + (gl.m + m_add) * self.gv
        M = np.cross(rb, f).sum(0) + np.cross(Rw, self.gv)
        E = np.concatenate([e_len, F / W, M / W])
        if not jac:
            return E
        n = self.n
        P = (np.eye(3)[None] - u[:, :, None] * u[:, None, :]) / l[:, None, None]
        Srb = skews(rb)
        Sf = skews(f)
        TP = T[:, None, None] * P
        Fy = np.zeros((n + 6, 6 + n))
        Fy[:n, 0:3] = np.cross(u, rb)
        Fy[:n, 3:6] = -u
        Fy[:n, 6:] = -np.diag(gl.comp)
        Fy[n:n + 3, 0:3] = np.einsum("nij,njk->ik", TP, Srb) / W
        Fy[n:n + 3, 3:6] = -TP.sum(0) / W
        Fy[n:n + 3, 6:] = u.T / W
        SrbTP = np.einsum("nij,njk->nik", Srb, TP)
        Fy[n + 3:, 0:3] = (np.einsum("nij,njk->ik", Sf, Srb) + np.einsum("nij,njk->ik", SrbTP, Srb)
                           + skew(self.gv) @ skew(Rw)) / W
        Fy[n + 3:, 3:6] = -SrbTP.sum(0) / W
        Fy[n + 3:, 6:] = np.cross(rb, u).T / W
        # derivatives w.r.t. the physical globals: c (3), C (1), m (1), L (N)
        Fc = np.zeros((n + 6, 3))
        Fc[n + 3:] = -gl.m * skew(self.gv) @ R / W
        FC = np.zeros(n + 6)
        FC[:n] = -T * (~self.known)
        # d/dm of the raw force (M gv) and moment (R m c × gv), scaled by 1/W (the derivative
        # of the 1/W scaling multiplies E, which vanishes at the equilibrium)
        Fm = np.zeros(n + 6)
        Fm[n:n + 3] = self.gv / W
        Fm[n + 3:] = np.cross(R @ gl.c, self.gv) / W
        FL = np.zeros((n + 6, n))
        FL[:n] = -np.eye(n)
        # added masses: d/dm_add (force) and d/dw_add (moment of their first moment, body frame)
        Fma = np.zeros(n + 6)
        Fma[n:n + 3] = self.gv / W
        Fwa = np.zeros((n + 6, 3))
        Fwa[n + 3:] = -skew(self.gv) @ R / W
        # anchors: ∂l_i/∂A_i = u_iᵀ, ∂u_i/∂A_i = P_i; b_i enters as -R b_i in v_i and as R b_i in the lever
        FA = np.zeros((n + 6, n, 3))
        FB = np.zeros((n + 6, n, 3))
        idx = np.arange(n)
        FA[idx, idx] = u
        FB[idx, idx] = -u @ R
        FA[n:n + 3] = np.transpose(TP, (1, 0, 2)) / W
        FB[n:n + 3] = -np.transpose(TP @ R, (1, 0, 2)) / W
        FA[n + 3:] = np.transpose(SrbTP, (1, 0, 2)) / W
        FB[n + 3:] = -np.transpose((Sf + SrbTP) @ R, (1, 0, 2)) / W
        return E, Fy, EquationPartials(Fc, FC, Fm, FL, Fma, Fwa, FA.reshape(n + 6, 3 * n), FB.reshape(n + 6, 3 * n))

    def solve_state(self, gl: GlobalUnknowns, m_add: float, w_add: np.ndarray, y0: tuple, label: str = "state"):
        """Equilibrium (R (3, 3), p (3,) m, T (N,) N) of one state for the globals ``gl``: Newton
        from ``y0`` = (R, p, T) with the analytic Jacobian of :meth:`equations`, steps damped far
        from the solution, the rotation updated as R <- exp([s δφ]×) R (``scipy.linalg.expm``).
        Raises :class:`~rig_identification.statics.state.StaticsError` (naming ``label``) when
        no equilibrium is found."""
        R, p, T = y0[0].copy(), y0[1].copy(), y0[2].copy()
        W = (gl.m + m_add) * self.g
        tsc = W / self.n
        for it in range(60):
            E, Fy, _ = self.equations(R, p, T, gl, m_add, w_add, jac=True)
            Fy_s = Fy.copy()
            Fy_s[:, 6:] *= tsc
            try:
                d = np.linalg.solve(Fy_s, -E)
            except np.linalg.LinAlgError:
                d = np.linalg.lstsq(Fy_s, -E, rcond=None)[0]
            # damp huge steps (far from the solution)
            s = 1.0
            big = max(np.abs(d[:3]).max() / 0.2, np.abs(d[3:6]).max() / 0.5, 1.0)
            if big > 1.0:
                s = 1.0 / big
            R = expm(skew(s * d[:3])) @ R
            p = p + s * d[3:6]
            T = T + s * d[6:] * tsc
            if np.abs(d[:6]).max() < 1e-13 and np.abs(d[6:]).max() < 1e-13 and s == 1.0:
                break
        E = self.equations(R, p, T, gl, m_add, w_add)
        if not np.all(np.isfinite(E)) or np.abs(E).max() > 1e-8:
            raise StaticsError(f"{label}: no equilibrium of the body on these cables for the data (equation "
                               f"residual {np.abs(E).max():.1e}): contradictory geometry or data (check rig.yaml's "
                               "anchors, cable lengths and masses)")
        return R, p, T

    # --- measurement predictions and their derivatives w.r.t. y = (δφ, p, T)
    def predict(self, R, T, gl: GlobalUnknowns):
        """(values (k,), d/dy (k, 6+N), d/dκ (k,), d/doff (k, 2)) of the measured quantities in
        the state (R, T): the load-cell readings T/κ N, the inclinometer elevations rad (plus the
        offsets) and the accelerometer's specific force m/s² (IMU axes), those used, in this order."""
        vals, Dy, Dk, Do = [], [], [], []
        n = self.n
        if self.tensions_used:
            vals.append(T / gl.kappa)
            d = np.zeros((n, 6 + n))
            d[:, 6:] = np.eye(n) / gl.kappa
            Dy.append(d)
            Dk.append(-T / gl.kappa**2)
            Do.append(np.zeros((n, 2)))
        if self.incl is not None:
            ax = R @ self.incl[:, :2]            # world directions of incl x, y (3, 2)
            e = np.arcsin(np.clip(ax[2], -1, 1))
            vals.append(e + gl.off)
            d = np.zeros((2, 6 + n))
            d[:, 0:3] = np.cross(ax.T, Z) / np.cos(e)[:, None]
            Dy.append(d)
            Dk.append(np.zeros(2))
            Do.append(np.eye(2))
        if self.accel_used:
            Mi = self.imu.T @ R.T
            vals.append(Mi @ (self.g * Z))
            d = np.zeros((3, 6 + n))
            d[:, 0:3] = Mi @ skew(self.g * Z)
            Dy.append(d)
            Dk.append(np.zeros(3))
            Do.append(np.zeros((3, 2)))
        return np.concatenate(vals), np.vstack(Dy), np.concatenate(Dk), np.vstack(Do)


# --- forward model: equilibrium states for planning and fast static simulation -------------------

def static_equilibrium(rig: Rig, mass: float, cg, added: Sequence[DummyMass] = (),
                       compliance: float | np.ndarray | None = None):
    """Equilibrium at rest of the body (mass kg, cg (3,) body m) plus ``added`` point masses.

    compliance: m/N of the cables without a stiffness in rig.yaml (scalar or (N,); default
    2e-7, i.e. 5e6 N/m; 0 = inextensible).  Same model as
    :func:`~rig_identification.statics.estimation.estimate_cg`.
    Returns (R (3, 3) body -> world, p (3,) world m of the body origin, T (N,) N).
    Raises :class:`StaticsError` if no equilibrium with taut cables exists.
    """
    k = rig.cable_stiffness
    known = np.isfinite(k)
    cu = DEFAULT_COMPLIANCE if compliance is None else compliance
    comp = np.where(known, 1.0 / np.where(known, k, 1.0), cu)
    m_add = sum(d.mass for d in added)
    w_add = sum((d.mass * d.position for d in added), np.zeros(3))
    M = mass + m_add
    cM = (mass * np.asarray(cg, float) + w_add) / M
    try:
        if np.all(comp > 0):
            cm = CableModel.spring(rig, M, stiffness=1.0 / comp)
        else:
            cm = CableModel.inextensible(compression=False)
        p0, rot0, T0 = equilibrium(rig, M, cM, cm)
    except SimulationError as e:
        raise StaticsError(f"no static equilibrium: {e}") from None
    opts = CgOptions(fit_compliance=False, fit_load_cell_gain=False)
    model = StaticModel(rig, opts, True, rig.inclinometer is not None, False)
    gl = GlobalUnknowns(np.asarray(cg, float), comp, float(mass), 1.0, np.zeros(2), rig.cable_lengths.copy(),
                        np.zeros((1, 3)), np.zeros(1))
    return model.solve_state(gl, m_add, w_add, (rot0.as_matrix(), p0, T0), "equilibrium")
