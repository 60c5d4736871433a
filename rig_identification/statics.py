"""Centre of gravity from the static experiment (thesis chapter 2, section 2.2), generalised.

The suspended body (vehicle + carrying frame) is recorded at rest twice: without (the
*baseline*) and with a dummy mass of known mass and position (the *dummy* state).  The
thesis (eqs. 2.6–2.25) found the pose of each state from the cable lengths and two
inclinometer angles, then the cable tensions and the CG from the equilibrium equations.
Our rig also measures every cable's tension, which over-determines the problem; this
module fits everything at once, weighted by the measured noise:

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

Frames and units (RECORDING_FORMAT.md): world z up, gravity (0, 0, -g); body frame fixed
to the carrying frame; SI units (m, kg, N, rad, s).  Errors: :class:`StaticsError` (a
``ValueError``) with one clear message.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple, Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from scipy.stats import chi2 as _chi2
from scipy.stats import norm as _norm

from .recording import SensorData, TimeSeries
from .rig import DummyMass, Rig
from .simulator import CableModel, SimulationError, equilibrium
from .tracker import TrackerError, inclinometer_elevations, static_pose
from .verdict import Check

Z = np.array([0.0, 0.0, 1.0])
DEFAULT_COMPLIANCE = 2e-7        # m/N: a steel cable of a few metres (k = 5e6 N/m), start value
DEFAULT_SCALE_REL_STD = 1e-3     # the scale's reading: 0.1 % (a typical floor scale), 1 σ
MASS_COVERAGE = 3.0              # mass disagreement warning: |Δ| > 3 σ combined
MOTION_P = 1e-4                  # per-channel p-value below which a state is "moving"
CHI2_P_WARN = 0.01               # global fit: p-value below which σ are inflated (Birge ratio)
SLACK_FRACTION = 0.01            # a cable carrying < 1 % of an even share of the weight is slack
# physical tolerances above which a misfit means contradictory input (not noise)
TOL_INCL = 5e-4                  # rad
TOL_TENSION_REL = 5e-3           # of the mean tension per cable
TOL_ACCEL = 5e-3                 # m/s^2
# The rig's geometry as surveyed, 1 σ per coordinate (the default of every fit; CgOptions, and
# rig-identify cg --anchor-std/--length-std/--dummy-position-std, set others).  A careful survey
# with a class II steel tape (EN ISO 8764 / EC class II: maximum permissible error
# ±(0.3 + 0.2 L/m) mm, ±1.1 mm over 4 m) or a laser distance meter (±1–1.5 mm) locates each
# anchor, the pin-to-pin cable length and the dummy mass's centre to about a millimetre.  On the
# reference static pair (visible_case16_static) these 1 mm make the CG height's σ 22× the noise's
# (9.4 mm against 0.43 mm; docs/cg.md).
DEFAULT_ANCHOR_STD = 1e-3        # m: every ceiling anchor (world) and body anchor (body) coordinate
DEFAULT_LENGTH_STD = 1e-3        # m: every unstretched cable length
DEFAULT_DUMMY_POSITION_STD = 1e-3  # m: every coordinate of the dummy mass's centre of gravity
# Model validation of the CG fit (CgValidation): a check fails beyond the two-sided 3 σ of a
# normal variable (p = 0.0027 per check; for a 2-dof Wald statistic the same p-value).
VALIDATION_SIGMA = 3.0
# contradictory geometry: the fit's χ² exceeds its dof by more than 20² (a 20 σ misfit, as the
# per-stream contradiction checks) and it needed an input moved by > 10 of its σ and > 5 mm
CONTRADICTION_CHI2 = 400.0
TOL_GEOMETRY = 5e-3              # m


class StaticsError(ValueError):
    """Inconsistent static-experiment input (slack cable, ineffective dummy, unreachable
    angles, moving body, contradictory geometry, missing data)."""


# --- small rotation helpers ------------------------------------------------------------------

def _skew(a) -> np.ndarray:
    x, y, z = a
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _skews(a: np.ndarray) -> np.ndarray:
    """(N, 3) -> (N, 3, 3) cross-product matrices."""
    out = np.zeros((len(a), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -a[:, 2], a[:, 1]
    out[:, 1, 0], out[:, 1, 2] = a[:, 2], -a[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -a[:, 1], a[:, 0]
    return out


def _expm(phi: np.ndarray) -> np.ndarray:
    """Rotation matrix exp([phi]x) (Rodrigues)."""
    t = float(np.linalg.norm(phi))
    K = _skew(phi)
    if t < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + (math.sin(t) / t) * K + ((1 - math.cos(t)) / t**2) * K @ K


def _rpy(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R).as_euler("xyz")


# --- stream statistics and static states ------------------------------------------------------

@dataclass
class StreamStats:
    """Mean of one sensor stream over a window.

    mean, std_of_mean, scatter: (k,) per channel (std_of_mean = scatter / sqrt(n) for a
    stationary stream, the batch-means standard error when motion is accepted).
    n: samples.  motion_p: (k,) p-value of the stationarity test (batch means vs the
    sample-to-sample noise; small = the stream still moves).
    """

    mean: np.ndarray
    std_of_mean: np.ndarray
    scatter: np.ndarray
    n: int
    motion_p: np.ndarray


def _batch_test(x: np.ndarray, K: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stationarity test of samples x (n, k) in K consecutive batches.

    Returns (p-value (k,), noise σ from first differences (k,), batch-means standard error
    of the mean (k,)).  Under white noise Σ n_b (x̄_b - x̄)² / σ² ~ χ²(K - 1).
    """
    n = len(x)
    edges = np.linspace(0, n, K + 1).astype(int)
    bm = np.array([x[a:b].mean(0) for a, b in zip(edges[:-1], edges[1:])])
    nb = np.diff(edges)[:, None]
    mean = x.mean(0)
    sd = np.sqrt(np.mean(np.diff(x, axis=0) ** 2, axis=0) / 2.0) if n > 2 else np.zeros(x.shape[1])
    floor = 1e-9 * (np.abs(mean) + 1.0)
    sd = np.maximum(sd, floor)
    q = np.sum(nb * (bm - mean) ** 2, axis=0) / sd**2
    p = _chi2.sf(q, K - 1)
    se_batch = np.sqrt(np.sum((bm - mean) ** 2, axis=0) / (K * (K - 1)))
    return p, sd, se_batch


def _stats(x: np.ndarray, K: int, accept_motion: bool) -> StreamStats:
    p, sd, se_b = _batch_test(x, K)
    n = len(x)
    scatter = x.std(0, ddof=1) if n > 1 else np.zeros(x.shape[1])
    floor = 1e-9 * (np.abs(x.mean(0)) + 1.0)
    scatter = np.maximum(scatter, floor)
    se = scatter / math.sqrt(n)
    if accept_motion:
        se = np.maximum(se, se_b)
    return StreamStats(x.mean(0), se, scatter, n, p)


@dataclass
class StaticState:
    """One static state of the body: the mean of every sensor stream over a window at rest.

    Attributes (means over the window, sensor frames of RECORDING_FORMAT.md):

    * ``cable_names`` (N,) and ``tensions`` (N,) N with ``tensions_std`` (N,) N (std of the
      mean), or ``None`` without load cells;
    * ``elevations`` (2,) rad, ``elevations_std`` (2,) rad: inclinometer x, y elevations
      (thesis's c31, c32 as angles), or ``None``;
    * ``specific_force`` (3,) m/s², ``specific_force_std`` (3,): accelerometer, IMU axes, or ``None``;
    * ``added``: dummy masses fixed on the body in this state (body frame), ``None`` = let
      :func:`estimate_cg` decide (baseline: none; dummy: ``rig.dummy_mass``);
    * ``window`` (t0, t1) header stamps s actually averaged, ``samples`` per stream,
      ``label``, ``warnings`` (e.g. the body still moved at the start and was trimmed),
      ``moving`` (accepted although the stationarity test failed), ``stats``
      (:class:`StreamStats` per stream: ``imu``, ``load_cell:<name>``, ``inclinometer``,
      ``exciter``) and ``exciter_force`` (2,) N (mean exciter reading, ignored by the fit).

    A node captures a state by buffering the live topics into a :class:`SensorData` and
    calling :meth:`from_window`; :func:`estimate_cg` then takes two (or more) states.
    """

    cable_names: tuple[str, ...] | None = None
    tensions: np.ndarray | None = None
    tensions_std: np.ndarray | None = None
    elevations: np.ndarray | None = None
    elevations_std: np.ndarray | None = None
    specific_force: np.ndarray | None = None
    specific_force_std: np.ndarray | None = None
    added: tuple[DummyMass, ...] | None = None
    window: tuple[float, float] = (0.0, 0.0)
    samples: dict = field(default_factory=dict)
    label: str = "state"
    warnings: list[str] = field(default_factory=list)
    moving: bool = False
    stats: dict = field(default_factory=dict)
    exciter_force: np.ndarray | None = None

    @classmethod
    def from_window(cls, sensors: SensorData, t0: float | None = None, t1: float | None = None,
                    label: str = "state", settle: bool = True, allow_motion: bool = False,
                    batch_seconds: float = 1.0, min_fraction: float = 0.4,
                    added: Sequence[DummyMass] | None = None) -> "StaticState":
        """Average every stream of ``sensors`` over header stamps [t0, t1] s (default: all).

        Stationarity: each channel's window is cut into ~``batch_seconds`` batches (5 to 20);
        if their means scatter more than the sample-to-sample noise allows (χ² test,
        p < 1e-4 on any channel: the body still swings or drifts) and ``settle`` is true,
        leading batches are dropped until the rest is at rest (at least ``min_fraction`` of
        the window); a warning says so.  If no quiet tail exists: :class:`StaticsError`
        ("the body still moves"), unless ``allow_motion`` (then the batch-means standard
        error is used and a warning is added).  ``added``: the dummy masses fixed in this
        state (body frame), if known here.  Raises :class:`StaticsError` for an empty window.
        """
        t0 = -np.inf if t0 is None else float(t0)
        t1 = np.inf if t1 is None else float(t1)
        streams: dict[str, TimeSeries] = {"imu": sensors.imu}
        for name, ts in sensors.load_cells.items():
            streams["load_cell:" + name] = ts
        if sensors.inclinometer is not None:
            streams["inclinometer"] = sensors.inclinometer
        if sensors.exciter is not None:
            streams["exciter"] = sensors.exciter
        win = {}
        for k, ts in streams.items():
            w = ts.window(t0, t1)
            if len(w) < 10:
                raise StaticsError(f"{label}: stream {k} has {len(w)} sample(s) in the window "
                                   f"[{t0:.3f}, {t1:.3f}] s; at least 10 are needed")
            win[k] = w
        a = max(w.t[0] for w in win.values())
        b = min(w.t[-1] for w in win.values())
        if b - a <= 0:
            raise StaticsError(f"{label}: the streams do not overlap in time")
        K = int(np.clip(round((b - a) / batch_seconds), 5, 20))

        def test(ta: float) -> tuple[float, str]:
            worst, what = 1.0, ""
            for k, w in win.items():
                x = w.window(ta, b).data
                if len(x) < 2 * K:
                    return 0.0, f"{k}: too few samples"
                p, _, _ = _batch_test(x, K)
                if p.min() < worst:
                    worst, what = float(p.min()), f"{k}[{int(np.argmin(p))}]"
            return worst, what

        warnings: list[str] = []
        start, moving = a, False
        p, what = test(a)
        if p < MOTION_P:
            found = False
            if settle:
                step = (b - a) / K
                j = 1
                while (b - (a + j * step)) >= min_fraction * (b - a) - 1e-9:
                    pj, _ = test(a + j * step)
                    if pj >= MOTION_P:
                        found, start = True, a + j * step
                        break
                    j += 1
            if found:
                warnings.append(f"{label}: the body still moved during the first {start - a:.1f} s "
                                f"({what} not stationary); averaged the last {b - start:.1f} s")
            elif allow_motion:
                moving = True
                warnings.append(f"{label}: the body still moves over the whole window ({what} not "
                                f"stationary, p = {p:.1e}); averaged anyway with the batch-means "
                                "uncertainty")
            else:
                raise StaticsError(f"{label}: the body still moves ({what} is not stationary over "
                                   f"{b - a:.1f} s, p = {p:.1e}): no state at rest to use; wait until it "
                                   "settles and record again")
        st = {}
        for k, w in win.items():
            x = w.window(start, b).data
            st[k] = _stats(x, K, moving)
        names = tuple(sensors.load_cells)
        tens = np.array([st["load_cell:" + n].mean[0] for n in names]) if names else None
        tens_sd = np.array([st["load_cell:" + n].std_of_mean[0] for n in names]) if names else None
        inc = st.get("inclinometer")
        imu = st["imu"]
        exc = st.get("exciter")
        if exc is not None:
            f = exc.mean
            if np.linalg.norm(f) > max(1.0, 5 * np.linalg.norm(exc.std_of_mean)):
                warnings.append(f"{label}: the exciter load cells read a mean force of "
                                f"{np.linalg.norm(f):.1f} N at rest; ignored (is the exciter off?)")
        return cls(cable_names=names or None, tensions=tens, tensions_std=tens_sd,
                   elevations=None if inc is None else inc.mean,
                   elevations_std=None if inc is None else inc.std_of_mean,
                   specific_force=imu.mean[3:6], specific_force_std=imu.std_of_mean[3:6],
                   added=None if added is None else tuple(added), window=(float(start), float(b)),
                   samples={k: v.n for k, v in st.items()}, label=label, warnings=warnings,
                   moving=moving, stats=st, exciter_force=None if exc is None else exc.mean)

    @classmethod
    def from_recording(cls, recording, label: str = "state", **kw) -> "StaticState":
        """:meth:`from_window` over a whole :class:`~.recording.Recording`."""
        st = cls.from_window(recording.sensors, label=label, **kw)
        st.warnings = [f"{recording.path}: {w}" for w in recording.warnings] + st.warnings
        return st

    def tensions_for(self, rig: Rig) -> tuple[np.ndarray, np.ndarray] | None:
        """(tensions (N,), std (N,)) in rig.yaml cable order, or None without load cells.

        Raises :class:`StaticsError` if a cable of the rig has no load cell here."""
        if self.tensions is None:
            return None
        idx = {n: i for i, n in enumerate(self.cable_names)}
        missing = [n for n in rig.cable_names if n not in idx]
        if missing:
            raise StaticsError(f"{self.label}: no load-cell reading for cable(s) {', '.join(missing)}")
        order = [idx[n] for n in rig.cable_names]
        return self.tensions[order], self.tensions_std[order]


# --- the mechanical model ---------------------------------------------------------------------

@dataclass
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
    def exact_geometry(cls, **kw) -> "CgOptions":
        """Options that take the rig's geometry and the dummy mass as exact (noise-only σ)."""
        return cls(**{"length_std": 0.0, "dummy_position_std": 0.0, "anchor_std": 0.0, **kw})

    def geometry_std(self) -> dict[str, float]:
        """The σ assumed for the systematic inputs (m, dummy_mass kg), by name."""
        return {"anchors": float(self.anchor_std), "cable_lengths": float(self.length_std),
                "dummy_position": float(self.dummy_position_std), "dummy_mass": float(self.dummy_mass_std)}


class _Layout:
    """Indices of the global unknowns θ (internal scaled units) and their scales."""

    def __init__(self, n_cables: int, fit_c: bool, fit_kappa: bool, fit_off: bool, fit_len: bool,
                 n_states: int = 2, fit_dpos: bool = False, fit_dmass: bool = False, fit_anchors: bool = False):
        self.names: list[str] = ["cg_x", "cg_y", "cg_z"]
        self.scale: list[float] = [1.0, 1.0, 1.0]
        self.fit_c, self.fit_kappa, self.fit_off, self.fit_len = fit_c, fit_kappa, fit_off, fit_len
        self.i_C = self._add("compliance", 1e-7) if fit_c else None
        self.i_m = self._add("mass", 1.0)
        self.i_k = self._add("load_cell_gain", 1e-3) if fit_kappa else None
        self.i_off = [self._add(f"incl_offset_{a}", 1e-3) for a in "xy"] if fit_off else None
        self.i_L = [self._add(f"length_{i}", 1e-3) for i in range(n_cables)] if fit_len else None
        # per dummy state (1 .. n_states-1): position offset (3) and mass offset of its dummy
        self.i_dd = [[self._add(f"dummy{s}_{a}", 1e-3) for a in "xyz"] for s in range(1, n_states)] \
            if fit_dpos else None
        self.i_dm = [self._add(f"dummy{s}_mass", 1.0) for s in range(1, n_states)] if fit_dmass else None
        # anchors: (N, 3) row-major, ceiling (world) then body (body frame)
        self.i_A = [self._add(f"ceiling_anchor_{i}_{a}", 1e-3) for i in range(n_cables) for a in "xyz"] \
            if fit_anchors else None
        self.i_B = [self._add(f"body_anchor_{i}_{a}", 1e-3) for i in range(n_cables) for a in "xyz"] \
            if fit_anchors else None
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


@dataclass
class _Global:
    c: np.ndarray
    comp: np.ndarray        # (N,) compliance per cable, m/N
    m: float
    kappa: float
    off: np.ndarray         # (2,) rad
    L: np.ndarray           # (N,) m
    dd: np.ndarray | None = None   # (S, 3) m: dummy position offsets per state (row 0 unused)
    dm: np.ndarray | None = None   # (S,) kg: dummy mass offsets per state
    A: np.ndarray | None = None    # (N, 3) world m: ceiling anchors (None: rig.yaml's)
    B: np.ndarray | None = None    # (N, 3) body m: body anchors (None: rig.yaml's)


class _Partials(NamedTuple):
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


class _Model:
    """Geometry and sensor layout of the rig; per-state equilibrium solve."""

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
        self.layout = _Layout(self.n, fit_c, opts.fit_load_cell_gain and tensions_used,
                              opts.fit_inclinometer_offset and self.incl is not None, opts.length_std > 0,
                              n_states, opts.dummy_position_std > 0, opts.dummy_mass_std > 0, opts.anchor_std > 0)

    # θ (internal) <-> physical
    def unpack(self, th: np.ndarray, fixed: _Global) -> _Global:
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
        return _Global(x[:3].copy(), comp, x[lay.i_m], kappa, np.asarray(off, float), np.asarray(L, float), dd, dm,
                       A, B)

    def pack(self, g: _Global) -> np.ndarray:
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
    def equations(self, R, p, T, gl: _Global, m_add: float, w_add: np.ndarray, jac: bool = False):
        """Scaled equilibrium equations E (N + 6,) of one state (module docstring): length
        (m), force (/ W) and moment (/ W m) balance.  With ``jac``: (E, ∂E/∂y (N+6, 6+N) for
        y = (δφ, p, T), :class:`_Partials`)."""
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
        Srb = _skews(rb)
        Sf = _skews(f)
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
                           + _skew(self.gv) @ _skew(Rw)) / W
        Fy[n + 3:, 3:6] = -SrbTP.sum(0) / W
        Fy[n + 3:, 6:] = np.cross(rb, u).T / W
        # derivatives w.r.t. the physical globals: c (3), C (1), m (1), L (N)
        Fc = np.zeros((n + 6, 3))
        Fc[n + 3:] = -gl.m * _skew(self.gv) @ R / W
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
        Fwa[n + 3:] = -_skew(self.gv) @ R / W
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
        return E, Fy, _Partials(Fc, FC, Fm, FL, Fma, Fwa, FA.reshape(n + 6, 3 * n), FB.reshape(n + 6, 3 * n))

    def solve_state(self, gl: _Global, m_add: float, w_add: np.ndarray, y0: tuple, label: str = "state"):
        """Equilibrium (R, p, T) of one state for the globals ``gl`` (Newton from ``y0``)."""
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
            R = _expm(s * d[:3]) @ R
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
    def predict(self, R, T, gl: _Global):
        """(values, d/dy (k, 6+N), d/dκ (k,), d/doff (k, 2)) of the measured quantities."""
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
            d[:, 0:3] = Mi @ _skew(self.g * Z)
            Dy.append(d)
            Dk.append(np.zeros(3))
            Do.append(np.zeros((3, 2)))
        return np.concatenate(vals), np.vstack(Dy), np.concatenate(Dk), np.vstack(Do)


def _added(rig: Rig, st: StaticState, is_baseline: bool) -> tuple[DummyMass, ...]:
    if st.added is not None:
        return st.added
    if is_baseline:
        return ()
    if rig.dummy_mass is None:
        raise StaticsError(f"{rig.source}: the rig description has no dummy_mass (mass and position of "
                           "the dummy mass of the static experiment)")
    return (rig.dummy_mass,)


# --- result ---------------------------------------------------------------------------------------

@dataclass
class StatePose:
    """Fitted equilibrium of one state: position (3,) world m of the body origin, rotation
    (3, 3) body -> world, rpy (3,) fixed-axis XYZ rad, tensions (N,) N (true, i.e. κ·reading),
    measured/predicted/normalised residuals of the streams used."""

    label: str
    position: np.ndarray
    rotation: np.ndarray
    tensions: np.ndarray
    added_mass: float
    window: tuple[float, float]
    residuals: dict

    @property
    def rpy(self) -> np.ndarray:
        return _rpy(self.rotation)


CG_RESULT_SCHEMA = "rig_identification.cg_result"   # the JSON of CgResult.to_dict / rig-identify cg --json
CG_RESULT_SCHEMA_VERSION = 1
CG_RESULT_UNITS = {
    "center_of_gravity": "m", "center_of_gravity_std": "m", "center_of_gravity_std_noise": "m",
    "center_of_gravity_covariance": "m^2", "mass": "kg", "mass_std": "kg", "mass_from_load_cells": "kg",
    "mass_from_load_cells_std": "kg", "mass_fitted": "kg", "mass_fitted_std": "kg", "load_cell_gain": "1",
    "load_cell_gain_std": "1", "cable_stiffness": "N/m", "cable_stiffness_std": "N/m", "cable_compliance": "m/N",
    "cable_compliance_std": "m/N", "inclinometer_offset": "rad", "states.position": "m (world)",
    "states.rpy": "rad (fixed-axis XYZ, body -> world)", "states.tensions": "N", "states.added_mass": "kg",
    "states.window": "s (header stamps)", "states.residuals_sigma": "1 (residual / its σ)",
    "weakly_determined.std": "m", "weakly_determined.tilt_change_rad": "rad",
    "sensitivity": "m per m of rig.yaml's value (dummy_mass: m/kg)", "uncertainty.geometry_std": "m (dummy_mass: kg)",
    "uncertainty.budget": "m", "validation.checks.statistic": "see each check's detail (σ, χ²/dof)"}
CG_VERDICTS = ("ok", "model_error")
# the checks that bear on the CG (a failure makes the verdict model_error); "mass" is a cross-check
CG_MODEL_CHECKS = ("fit_chi2", "tilt_change", "inclinometer_level")


@dataclass(frozen=True)
class CgValidation:
    """Model validation of a CG fit: ``verdict`` (one of :data:`CG_VERDICTS`: ``model_error``
    when a check of :data:`CG_MODEL_CHECKS` failed) and the :class:`~.verdict.Check` list:

    * ``fit_chi2``: χ²/dof of the whole fit (threshold: its 99th percentile);
    * ``tilt_change``: the inclinometer's change of elevation between the baseline and each
      dummy state against the rigid-body equilibrium's with the fitted CG (a Wald statistic
      over the residual's own covariance, said as the equivalent two-sided normal σ; threshold
      :data:`VALIDATION_SIGMA`): a body that tilts more (or less) than the frame under the
      dummy's moment allows -- a vehicle on an unlocked suspension, an inclinometer on the
      sprung body, a load that shifted, an inclinometer that moved between the recordings;
    * ``inclinometer_level``: the same for the mean of the states' elevations: an inclinometer
      zero offset or mounting error (``inclinometer.rpy``), or rig geometry off beyond its σ;
    * ``mass``: the load cells' weight against the scale's, in combined σ (threshold 3).

    A check whose residual the fit absorbs entirely (no redundancy) is not applicable
    (statistic None)."""

    verdict: str
    checks: tuple[Check, ...]

    @property
    def failed(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.checks if c.passed is False)

    @property
    def summary(self) -> str:
        """The verdict in words (first line of the text output)."""
        if self.verdict == "ok":
            return ("validation: ok — the static states agree with a rigid body on these cables (checks "
                    + ", ".join(c.name for c in self.checks if c.passed) + " passed)")
        bad = [c.name for c in self.checks if c.passed is False and c.name in CG_MODEL_CHECKS]
        return ("validation: MODEL ERROR — the static states disagree with a rigid body on these cables ("
                + ", ".join(bad) + " failed): the CG below is not trustworthy")

    def to_dict(self) -> dict:
        return {"verdict": self.verdict, "failed": list(self.failed), "checks": [c.to_dict() for c in self.checks]}


@dataclass
class CgResult:
    """The static experiment's estimate.

    center_of_gravity (3,) body frame m; center_of_gravity_std (3,) m and covariance (3, 3) m²:
    the measurement noise AND the rig's geometry as surveyed (``geometry_std``: the σ assumed
    for the anchors, cable lengths m, dummy position m and dummy mass kg, see :class:`CgOptions`);
    center_of_gravity_std_noise (3,) m: the measurement noise alone (the geometry taken as
    exact, what the fit reported before geometry σ were assumed); budget: the σ (3,) m each
    source contributes -- ``measurement_noise``, ``scale``, ``cable_lengths``, ``dummy_position``,
    ``dummy_mass``, ``ceiling_anchors``, ``body_anchors`` (those fitted) -- which add in
    quadrature to center_of_gravity_std;
    mass: the scale's reading (rig.yaml) kg with mass_std (the σ assumed for it);
    mass_from_load_cells (sum of the baseline's vertical tension components / g) kg with its
    std, or None without load cells -- a warning says when it and the scale disagree by more
    than 3 combined σ; mass_fitted: the body mass of the fit (with load cells: theirs, times
    the gain the dummy mass calibrates; without: the scale's); load_cell_gain (κ: true tension = κ · reading)
    and std, or None; cable_compliance m/N (std): the fitted common compliance of the cables
    without a stiffness in rig.yaml, or None, and cable_stiffness = its inverse N/m (None when
    the compliance is not significantly > 0, e.g. inextensible cables); states: the fitted :class:`StatePose` of each state;
    chi2, dof of the fit; weakly_determined: the CG direction the data determine worst
    (axis, direction, std, tilt change); sensitivity: ∂CG/∂(rig.yaml value) of each systematic
    input, the same definition whether the input is fitted with its σ or taken as exact --
    ``dummy_position`` (3, 3) m/m (first dummy state), ``dummy_mass`` (3,) m/kg,
    ``cable_lengths`` (3, N) m/m, ``ceiling_anchors`` and ``body_anchors`` (3, 3N) m/m (cable
    by cable, x y z); validation: the :class:`CgValidation`; warnings: texts for the user.
    """

    center_of_gravity: np.ndarray
    center_of_gravity_std: np.ndarray
    covariance: np.ndarray
    mass: float
    mass_std: float
    mass_from_load_cells: float | None
    mass_from_load_cells_std: float | None
    mass_fitted: float
    mass_fitted_std: float
    load_cell_gain: float | None
    load_cell_gain_std: float | None
    cable_stiffness: float | None
    cable_stiffness_std: float | None
    cable_compliance: float | None
    cable_compliance_std: float | None
    inclinometer_offset: np.ndarray | None
    states: list[StatePose]
    chi2: float
    dof: int
    inflation: float
    weakly_determined: dict
    warnings: list[str]
    parameter_names: list[str]
    parameter_covariance: np.ndarray
    streams: list[str]
    sensitivity: dict = field(default_factory=dict)
    center_of_gravity_std_noise: np.ndarray | None = None
    geometry_std: dict = field(default_factory=dict)
    budget: dict = field(default_factory=dict)
    validation: CgValidation | None = None

    def without(self, mass: float, cg) -> tuple[np.ndarray, np.ndarray]:
        """CG (3,) and σ (3,) body frame m of the suspended body minus a known part (e.g. the
        carrying frame: ``mass`` kg with its CG ``cg`` (3,) body m), using the scale mass."""
        M = self.mass
        k = M / (M - mass)
        c = (M * self.center_of_gravity - mass * np.asarray(cg, float)) / (M - mass)
        return c, k * self.center_of_gravity_std

    def to_dict(self) -> dict:
        """JSON-ready mapping (lists and floats only): the file format ``rig-identify cg --json``
        prints, ``schema`` :data:`CG_RESULT_SCHEMA` version :data:`CG_RESULT_SCHEMA_VERSION`,
        ``units`` per field (:data:`CG_RESULT_UNITS`); read back by ``cg_cli.load_cg_result``."""
        def f(x):
            return None if x is None else float(x)

        def v(a):
            return None if a is None else [float(x) for x in np.ravel(a)]
        return {
            "schema": CG_RESULT_SCHEMA, "schema_version": CG_RESULT_SCHEMA_VERSION, "units": dict(CG_RESULT_UNITS),
            "center_of_gravity": v(self.center_of_gravity),
            "center_of_gravity_std": v(self.center_of_gravity_std),
            "center_of_gravity_covariance": [v(r) for r in self.covariance],
            "frame": "body",
            "mass": f(self.mass), "mass_std": f(self.mass_std),
            "mass_from_load_cells": f(self.mass_from_load_cells),
            "mass_from_load_cells_std": f(self.mass_from_load_cells_std),
            "mass_fitted": f(self.mass_fitted), "mass_fitted_std": f(self.mass_fitted_std),
            "load_cell_gain": f(self.load_cell_gain), "load_cell_gain_std": f(self.load_cell_gain_std),
            "cable_stiffness": f(self.cable_stiffness), "cable_stiffness_std": f(self.cable_stiffness_std),
            "cable_compliance": f(self.cable_compliance), "cable_compliance_std": f(self.cable_compliance_std),
            "inclinometer_offset": v(self.inclinometer_offset),
            "states": [{"label": s.label, "position": v(s.position), "rpy": v(s.rpy),
                        "tensions": v(s.tensions), "added_mass": f(s.added_mass),
                        "window": v(s.window),
                        "residuals_sigma": {k: v(r["normalised"]) for k, r in s.residuals.items()}}
                       for s in self.states],
            "streams": list(self.streams),
            "chi2": f(self.chi2), "dof": int(self.dof), "sigma_inflation": f(self.inflation),
            "weakly_determined": self.weakly_determined,
            "sensitivity": {k: np.asarray(val).tolist() for k, val in self.sensitivity.items()},
            "center_of_gravity_std_noise": v(self.center_of_gravity_std_noise),
            "uncertainty": {
                "center_of_gravity_std": "measurement noise and the rig's geometry (geometry_std)",
                "center_of_gravity_std_noise": "measurement noise alone (geometry taken as exact)",
                "geometry_std": dict(self.geometry_std),
                "budget": {k: v(val) for k, val in self.budget.items()}},
            "validation": None if self.validation is None else self.validation.to_dict(),
            "warnings": list(self.warnings),
        }


# --- the estimator --------------------------------------------------------------------------------

def _initial_pose(rig: Rig, tens, elev, label: str):
    """Pose at rest from the lengths, tensions and angles (tracker.static_pose); diagnoses
    which input is out of line when no pose fits."""
    try:
        return static_pose(rig, tensions=tens, elevations=elev)
    except TrackerError:
        pass
    deg = "°, ".join(f"{np.degrees(x):.3f}" for x in (elev if elev is not None else [])) + "°"
    if elev is not None:
        try:
            static_pose(rig, tensions=None, elevations=elev)
        except TrackerError:
            raise StaticsError(f"{label}: the inclinometer reads {deg} but no pose of the body on these cables "
                               "has that tilt: angles outside the geometry's reach (check rig.yaml's cable "
                               "lengths and anchors, and inclinometer.rpy)") from None
        if tens is not None:
            try:
                ps = static_pose(rig, tensions=tens, elevations=None)
            except TrackerError:
                pass
            else:
                e = inclinometer_elevations(ps.rotation, rig.inclinometer.rotation)
                raise StaticsError(f"{label}: the inclinometer reads {deg} but the cables and load cells hold the "
                                   f"body at {np.degrees(e[0]):.3f}°, {np.degrees(e[1]):.3f}°: angles outside what "
                                   "the geometry allows (check inclinometer.rpy and its mounting)")
    raise StaticsError(f"{label}: no pose of the body matches the cable lengths and the load cells "
                       "(contradictory geometry: check rig.yaml's anchors and cable lengths)")


def estimate_cg(rig: Rig, baseline: StaticState, dummy: StaticState | Sequence[StaticState],
                options: CgOptions | None = None) -> CgResult:
    """CG of the suspended body from a baseline and one or more dummy-mass static states.

    rig: the rig description (its ``center_of_gravity`` is ignored; ``dummy_mass`` is used
    for a dummy state whose ``added`` is ``None``).  baseline: the body alone (its CG is the
    one reported); dummy: the body with the dummy mass(es) ``added`` (a list of states for
    several dummy positions).  Thesis section 2.2, eqs. 2.6–2.25, generalised to N >= 3
    cables, stretched cables, load cells (see the module docstring).

    options: :class:`CgOptions` (default: load cells and inclinometer, the rig's geometry
    with the survey σ of :data:`DEFAULT_ANCHOR_STD` etc.).

    Returns :class:`CgResult`: CG (3,) body frame m with σ (noise and geometry) and the σ of
    the noise alone, the σ budget, the sensitivities and the :class:`CgValidation` (a failed
    ``tilt_change`` or ``inclinometer_level`` check adds a warning).  Raises
    :class:`StaticsError`: a slack cable, a dummy mass that changed neither the load nor the
    inclination, angles outside the geometry's reach, a moving body, contradictory geometry or
    data (a stream misfit of > 20 σ, or a fit that needs a systematic input moved by > 10 of
    its σ and > 5 mm with χ² > dof + :data:`CONTRADICTION_CHI2`: the message names the input).
    """
    opts = options or CgOptions()
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

    # --- input checks: slack cables, dummy effect
    W_scale = rig.mass * rig.gravity
    if have_T:
        for s, (T, Tsd) in zip(states, tens):
            share = W_scale / len(T)
            slack = np.flatnonzero(T < SLACK_FRACTION * share)
            if slack.size:
                i = slack[0]
                raise StaticsError(f"{s.label}: cable {rig.cable_names[i]} is slack (mean tension {T[i]:.1f} N, "
                                   f"an even share of the weight is {share:.0f} N); the static experiment "
                                   "needs every cable taut")
    poses = [_initial_pose(rig, None if t is None else t[0], s.elevations if have_e else None, s.label)
             for s, t in zip(states, tens)]
    if have_T:
        Wz = []
        for (T, _), ps in zip(tens, poses):
            v = rig.ceiling_anchors - (ps.position + ps.rotation.apply(rig.body_anchors))
            Wz.append(float(T @ (v[:, 2] / np.linalg.norm(v, axis=1))))
        for s, Wd, md in zip(states[1:], Wz[1:], m_add[1:]):
            ratio = (Wd - Wz[0]) / (md * rig.gravity) if md > 0 else 1.0
            if md > 0 and ratio < 0.3:
                hint = " (are the two recordings swapped?)" if ratio < -0.3 else " (was the dummy mass attached?)"
                raise StaticsError(f"{s.label}: the load cells carry {(Wd - Wz[0]) / rig.gravity:+.1f} kg more than "
                                   f"in the baseline, but the dummy mass is {md:g} kg{hint}")
            if md > 0 and not 0.8 < ratio < 1.25:
                warnings.append(f"{s.label}: the load cells see {(Wd - Wz[0]) / rig.gravity:.1f} kg added, the "
                                f"dummy mass is {md:g} kg (load-cell gain {1 / ratio:.3f}?)")
    # tilt change: measured by the inclinometer when there is one, else from the tension poses
    for s, ps in zip(states[1:], poses[1:]):
        if have_e:
            d = s.elevations - baseline.elevations
            sd = np.hypot(s.elevations_std, baseline.elevations_std)
        else:
            d = (ps.rotation * poses[0].rotation.inv()).as_rotvec()[:2]
            sd = np.full(2, 1e-6)
        if not np.any(np.abs(d) > np.maximum(5 * sd, 1e-7)):
            raise StaticsError(f"{s.label}: the dummy mass did not change the inclination (change "
                               f"{d[0] * 1e6:+.1f}, {d[1] * 1e6:+.1f} µrad, noise σ {sd[0] * 1e6:.1f}, "
                               f"{sd[1] * 1e6:.1f} µrad): the CG height cannot be found; fix the dummy mass "
                               "farther from the vertical through the CG")

    model = _Model(rig, opts, have_T, have_e, have_a, len(states))
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
    scale_std = opts.scale_std if opts.scale_std is not None else DEFAULT_SCALE_REL_STD * rig.mass

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
            A.append(-m0 * _skew(model.gv) @ R)
            b.append(-Mc)
    if A:
        c0 = np.linalg.lstsq(np.vstack(A), np.concatenate(b), rcond=None)[0]
    else:
        c0 = rig.body_anchors.mean(0) - np.array([0.0, 0.0, 1.0])
    fixed = _Global(c0, comp0, m0, kappa0, np.zeros(2), rig.cable_lengths.copy(),
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
        res = {}
        k = 0
        if have_T:
            d = meas[i][k:k + model.n] - pred[k:k + model.n]
            rn = d / sig[i][k:k + model.n]
            res["load_cells"] = {"misfit": d, "normalised": rn}
            bad = (np.abs(rn) > 20) & (np.abs(d) > TOL_TENSION_REL * np.abs(meas[i][k:k + model.n]))
            if bad.any():
                j = int(np.flatnonzero(bad)[0])
                raise StaticsError(f"{s.label}: the load cell of cable {rig.cable_names[j]} reads {meas[i][k + j]:.1f} N "
                                   f"but the best equilibrium of this geometry needs {pred[k + j]:.1f} N: "
                                   "contradictory geometry or data (check rig.yaml's anchors, lengths, masses)")
            k += model.n
        if have_e:
            d = meas[i][k:k + 2] - pred[k:k + 2]
            rn = d / sig[i][k:k + 2]
            res["inclinometer"] = {"misfit": d, "normalised": rn}
            if np.any((np.abs(rn) > 20) & (np.abs(d) > TOL_INCL)):
                raise StaticsError(f"{s.label}: the inclinometer reads {np.degrees(meas[i][k]):.3f}°, "
                                   f"{np.degrees(meas[i][k + 1]):.3f}° but the body's equilibrium on these cables "
                                   f"has {np.degrees(pred[k]):.3f}°, {np.degrees(pred[k + 1]):.3f}°: angles outside "
                                   "what the geometry allows (contradictory geometry or inclinometer mounting)")
            k += 2
        if have_a:
            d = meas[i][k:k + 3] - pred[k:k + 3]
            rn = d / sig[i][k:k + 3]
            res["accelerometer"] = {"misfit": d, "normalised": rn}
            if np.any((np.abs(rn) > 20) & (np.abs(d) > TOL_ACCEL)):
                raise StaticsError(f"{s.label}: the accelerometer's gravity direction contradicts the equilibrium "
                                   "pose (check imu.rpy or use_accelerometer=False)")
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
    validation = _validate(r, U, incl_rows, [s.label for s in states], chi2, int(dof), mass_check,
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


def _input_deviations(gl: _Global, model: _Model, opts: CgOptions, rig: Rig,
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


def _wald_sigma(d: np.ndarray, V: np.ndarray, V_raw: np.ndarray) -> tuple[float | None, int]:
    """Wald statistic dᵀV⁺d of residual combinations d (k,) with covariance V (k, k), said
    as the two-sided normal σ of the same p-value (χ² with the rank as dof), and that rank.
    The pseudo-inverse keeps the eigen-directions whose variance exceeds 1e-4 of the largest
    variance the same combinations of the raw measurements have (V_raw): a residual the fit
    absorbs to within 1 % of its σ is not tested.  (None, 0) when none is left."""
    ev, Q = np.linalg.eigh(0.5 * (V + V.T))
    keep = ev > 1e-4 * max(float(np.linalg.eigvalsh(V_raw).max()), 1e-300)
    k = int(keep.sum())
    if k == 0:
        return None, 0
    z = Q[:, keep].T @ d
    w = float(np.sum(z**2 / ev[keep]))
    p = float(_chi2.sf(w, k))
    return float(_norm.isf(max(p, 1e-300) / 2.0)), k


def _validate(r: np.ndarray, U: np.ndarray, incl_rows: list, labels: list[str], chi2: float, dof: int,
              mass_check: Check | None, offset_fitted: bool) -> CgValidation:
    """The :class:`CgValidation` of a fit: normalised residuals r (n,), U (n, p) the left
    singular vectors of the fit's Jacobian (so that the residuals' covariance under the model
    is I − U Uᵀ, the linearised least-squares result), incl_rows: per state (row of elevation x,
    row of elevation y, their σ (2,) rad) or empty without an inclinometer."""
    checks = []
    if dof > 0:
        thr = float(_chi2.ppf(1 - CHI2_P_WARN, dof))
        checks.append(Check("fit_chi2", chi2 / dof, thr / dof, bool(chi2 <= thr),
                            f"χ²/dof {chi2 / dof:.2f} ({dof} dof), p = {_chi2.sf(chi2, dof):.2g}; threshold "
                            f"{thr / dof:.2f} (p = {CHI2_P_WARN:g})"))
    else:
        checks.append(Check("fit_chi2", None, None, None, "no degrees of freedom: nothing to test"))
    n = len(r)
    cov_r = np.eye(n) - U @ U.T

    def combo(weights: list[tuple[int, float]]) -> np.ndarray:
        a = np.zeros(n)
        for row, wgt in weights:
            a[row] += wgt
        return a

    if incl_rows:
        base = incl_rows[0]
        A_t, A_l = [], []
        for st in incl_rows[1:]:
            for ax in range(2):
                A_t.append(combo([(st[ax], st[2][ax]), (base[ax], -base[2][ax])]))
        S = len(incl_rows)
        for ax in range(2):
            A_l.append(combo([(st[ax], st[2][ax] / S) for st in incl_rows]))
        for name, A, what in (
                ("tilt_change", np.array(A_t),
                 "the inclinometer's change of elevation x, y from the baseline to the " + ", ".join(labels[1:])),
                ("inclinometer_level", np.array(A_l), "the inclinometer's mean elevation x, y over the states")):
            d = A @ r
            z, k = _wald_sigma(d, A @ cov_r @ A.T, A @ A.T)
            V = A @ cov_r @ A.T
            if name == "inclinometer_level" and offset_fitted:
                z = None
            if z is None:
                checks.append(Check(name, None, None, None, f"{what}: not testable (the fit absorbs it: no redundancy"
                                    + (", inclinometer offsets fitted"
                                       if offset_fitted and name != "tilt_change" else "")
                                    + ")"))
                continue
            text = ", ".join(f"{x * 1e6:+.1f}" for x in d) + " µrad"
            sd = ", ".join(f"{math.sqrt(max(x, 0.0)) * 1e6:.1f}" for x in np.diag(V))
            ok = z <= VALIDATION_SIGMA
            why = ""
            if not ok and name == "tilt_change":
                why = ("; the body tilts more (or less) under the dummy mass than a rigid body with the fitted CG on "
                       "these cables: a compliant body (a vehicle on an unlocked suspension, its sprung mass shifting "
                       "as the frame tilts; or an inclinometer on the sprung body), a load that shifted or an "
                       "inclinometer that moved between the recordings -- lock the suspension (or fix the load) and "
                       "record both states again")
            if not ok and name == "inclinometer_level":
                why = ("; the inclinometer's zero or mounting (rig.yaml inclinometer.rpy) disagrees with the pose the "
                       "cables and load cells give, or the geometry is off beyond its σ: check inclinometer.rpy, "
                       "or fit its offsets (--fit-inclinometer-offset)")
            checks.append(Check(name, z, VALIDATION_SIGMA, bool(ok),
                                f"{what} differs from the rigid-body equilibrium's by {text} (σ of the difference "
                                f"{sd} µrad): {z:.1f} σ ({k} dof), threshold {VALIDATION_SIGMA:g} σ{why}"))
    else:
        for name in ("tilt_change", "inclinometer_level"):
            checks.append(Check(name, None, None, None, "no inclinometer in the fit"))
    if mass_check is not None:
        checks.append(mass_check)
    bad = any(c.passed is False and c.name in CG_MODEL_CHECKS for c in checks)
    return CgValidation("model_error" if bad else "ok", tuple(checks))


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


# --- forward model: equilibrium states for planning and fast static simulation -------------------

def static_equilibrium(rig: Rig, mass: float, cg, added: Sequence[DummyMass] = (),
                       compliance: float | np.ndarray | None = None):
    """Equilibrium at rest of the body (mass kg, cg (3,) body m) plus ``added`` point masses.

    compliance: m/N of the cables without a stiffness in rig.yaml (scalar or (N,); default
    2e-7, i.e. 5e6 N/m; 0 = inextensible).  Same model as :func:`estimate_cg`.
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
    model = _Model(rig, opts, True, rig.inclinometer is not None, False)
    gl = _Global(np.asarray(cg, float), comp, float(mass), 1.0, np.zeros(2), rig.cable_lengths.copy(),
                 np.zeros((1, 3)), np.zeros(1))
    return model.solve_state(gl, m_add, w_add, (rot0.as_matrix(), p0, T0), "equilibrium")


@dataclass
class SensorNoise:
    """White-noise σ and rates of the rig's sensors (defaults: the reference recordings).

    load_cell N, inclinometer rad, accelerometer m/s², gyro rad/s, exciter N; rates Hz.
    """

    load_cell: float = 0.5
    inclinometer: float = 2e-4
    accelerometer: float = 0.01
    gyro: float = 0.002
    exciter: float = 0.5
    rate_load_cells: float = 200.0
    rate_inclinometer: float = 50.0
    rate_imu: float = 200.0
    rate_exciter: float = 200.0

    @classmethod
    def from_state(cls, st: StaticState, duration: float | None = None) -> "SensorNoise":
        """The scatter and rates measured in a :class:`StaticState` (window length = duration)."""
        d = duration or (st.window[1] - st.window[0])
        kw = {}
        s = st.stats
        cells = [v for k, v in s.items() if k.startswith("load_cell:")]
        if cells:
            kw["load_cell"] = float(np.sqrt(np.mean([c.scatter[0] ** 2 for c in cells])))
            kw["rate_load_cells"] = (cells[0].n - 1) / d
        if "inclinometer" in s:
            kw["inclinometer"] = float(np.sqrt(np.mean(s["inclinometer"].scatter ** 2)))
            kw["rate_inclinometer"] = (s["inclinometer"].n - 1) / d
        if "imu" in s:
            kw["accelerometer"] = float(np.sqrt(np.mean(s["imu"].scatter[3:] ** 2)))
            kw["gyro"] = float(np.sqrt(np.mean(s["imu"].scatter[:3] ** 2)))
            kw["rate_imu"] = (s["imu"].n - 1) / d
        return cls(**kw)


def _ideal_state(rig: Rig, R, T, duration: float, noise: SensorNoise, added, label) -> StaticState:
    """The noise-free means of a state with the σ of the mean a ``duration`` s window would give."""
    n_T = max(1, int(duration * noise.rate_load_cells))
    n_e = max(1, int(duration * noise.rate_inclinometer))
    n_a = max(1, int(duration * noise.rate_imu))
    elev = None
    if rig.inclinometer is not None:
        ax = R @ rig.inclinometer.rotation.as_matrix()
        elev = np.arcsin(np.clip(ax[2, :2], -1, 1))
    f = rig.imu.rotation.as_matrix().T @ R.T @ (rig.gravity * Z)
    return StaticState(tuple(rig.cable_names), T.copy(), np.full(len(T), noise.load_cell / math.sqrt(n_T)),
                       elev, None if elev is None else np.full(2, noise.inclinometer / math.sqrt(n_e)),
                       f, np.full(3, noise.accelerometer / math.sqrt(n_a)), tuple(added), (0.0, duration),
                       label=label)


def predict_cg_std(rig: Rig, cg, dummy: DummyMass, duration: float, noise: SensorNoise | None = None,
                   options: CgOptions | None = None, compliance: float | None = None) -> CgResult:
    """Predicted estimate of a planned static test (experiment design).

    The two states are solved at equilibrium for the assumed CG ``cg`` (3,) body m (a
    guess), the rig's mass and the dummy mass ``dummy`` (mass kg, position body m), each
    averaged for ``duration`` s with the sensor ``noise``; the estimator's covariance at
    these noise-free means is the CG covariance the test will have (``center_of_gravity_std``
    (3,) m, with the geometry σ of ``options`` -- by default the 1 mm survey; the noise alone:
    ``center_of_gravity_std_noise``).  Raises :class:`StaticsError` (no equilibrium, slack
    cable, ineffective dummy).
    """
    noise = noise or SensorNoise()
    opts = options or CgOptions()
    R0, p0, T0 = static_equilibrium(rig, rig.mass, cg, (), compliance)
    R1, p1, T1 = static_equilibrium(rig, rig.mass, cg, (dummy,), compliance)
    b = _ideal_state(rig, R0, T0, duration, noise, (), "baseline")
    d = _ideal_state(rig, R1, T1, duration, noise, (dummy,), "dummy")
    return estimate_cg(rig, b, d, replace(opts, inflate=False))


@dataclass
class CgPlan:
    """A planned static test: dummy mass kg, position (3,) body m, averaging time s per
    state, predicted CG σ (3,) m, the tilt change it causes rad, the lowest cable
    tension N over both states, whether it reaches the target, and ``floor``: the CG σ (3,) m
    no averaging time goes below (the systematic inputs' share: geometry σ of :class:`CgOptions`)."""

    dummy: DummyMass
    duration: float
    std: np.ndarray
    tilt_change: float
    min_tension: float
    reaches_target: bool
    floor: np.ndarray | None = None

    def to_dict(self) -> dict:
        return {"dummy_mass": float(self.dummy.mass), "dummy_position": [float(x) for x in self.dummy.position],
                "duration": float(self.duration), "center_of_gravity_std": [float(x) for x in self.std],
                "center_of_gravity_std_floor": None if self.floor is None else [float(x) for x in self.floor],
                "half_width_95": [float(1.96 * x) for x in self.std], "tilt_change_rad": float(self.tilt_change),
                "min_tension": float(self.min_tension), "reaches_target": bool(self.reaches_target)}


def candidate_positions(rig: Rig) -> list[np.ndarray]:
    """Default dummy-mass positions to try (body frame): the body anchors and the corners of
    their horizontal bounding box 1 m below them (where a carrying frame has mounting points)."""
    b = rig.body_anchors
    lo, hi = b.min(0), b.max(0)
    out = [x.copy() for x in b]
    ztop = b[:, 2].mean()
    for x in (lo[0], hi[0]):
        for y in (lo[1], hi[1]):
            out.append(np.array([x, y, ztop - 1.0]))
    uniq = []
    for p in out:
        if not any(np.allclose(p, q) for q in uniq):
            uniq.append(p)
    return uniq


def plan_static_test(rig: Rig, cg_guess, masses: Sequence[float] = (25.0, 50.0, 100.0, 200.0),
                     positions: Sequence | None = None, target: float = 2.5e-3,
                     noise: SensorNoise | None = None, max_duration: float = 600.0,
                     options: CgOptions | None = None, max_tilt: float = math.radians(5.0),
                     min_tension_fraction: float = 0.1) -> tuple[CgPlan | None, list[CgPlan]]:
    """Recommend a static test reaching ±``target`` m (1.96 σ) on every CG coordinate.

    For every dummy mass (kg) in ``masses`` and position (body m; default
    :func:`candidate_positions`), the CG variance is predicted (:func:`predict_cg_std`) at 10 s
    and 100 s of averaging per state and modelled per coordinate as σ²(t) = a/t + b (the
    noise of the means averages down, priors such as the dummy-position σ do not); the
    shortest time (rounded up to 5 s, at least 10 s) reaching the target is re-checked.
    Plans that tilt the body by more than ``max_tilt`` rad or leave a cable below
    ``min_tension_fraction`` of an even share of the weight are skipped.  The recommendation
    is the plan reaching the target within ``max_duration`` s with the shortest time, then
    the smallest mass, then the smallest σ.

    Returns (recommended :class:`CgPlan` or None, every evaluated plan -- for those that cannot
    reach the target, ``duration`` is ``max_duration`` and ``reaches_target`` false).
    """
    noise = noise or SensorNoise()
    positions = candidate_positions(rig) if positions is None else [np.asarray(p, float) for p in positions]
    share = rig.mass * rig.gravity / len(rig.cables)
    s2 = (target / 1.96) ** 2
    plans = []
    for m in masses:
        for pos in positions:
            dm = DummyMass(float(m), np.asarray(pos, float))
            try:
                r10 = predict_cg_std(rig, cg_guess, dm, 10.0, noise, options)
                r100 = predict_cg_std(rig, cg_guess, dm, 100.0, noise, options)
            except StaticsError:
                continue
            tilt = r10.weakly_determined["tilt_change_rad"]
            tmin = min(float(st.tensions.min()) for st in r10.states)
            if tilt > max_tilt or tmin < min_tension_fraction * share:
                continue
            v10, v100 = r10.center_of_gravity_std ** 2, r100.center_of_gravity_std ** 2
            a = np.maximum((v10 - v100) / (1 / 10.0 - 1 / 100.0), 0.0)
            bb = np.maximum(v100 - a / 100.0, 0.0)
            if np.any(bb >= s2):
                need = np.inf
            else:
                need = float(np.max(a / (s2 - bb)))
            dur = max(10.0, 5.0 * math.ceil(min(need, 1e9) / 5.0 - 1e-9))
            floor = np.sqrt(bb)
            if dur > max_duration:
                r = predict_cg_std(rig, cg_guess, dm, max_duration, noise, options)
                plans.append(CgPlan(dm, max_duration, r.center_of_gravity_std, tilt, tmin, False, floor))
                continue
            r = r10 if dur == 10.0 else predict_cg_std(rig, cg_guess, dm, dur, noise, options)
            while np.any(1.96 * r.center_of_gravity_std > target) and dur + 5.0 <= max_duration:
                dur += 5.0
                r = predict_cg_std(rig, cg_guess, dm, dur, noise, options)
            ok = bool(np.all(1.96 * r.center_of_gravity_std <= target))
            plans.append(CgPlan(dm, dur, r.center_of_gravity_std, tilt, tmin, ok, floor))
    feasible = [p for p in plans if p.reaches_target]
    best = min(feasible, key=lambda p: (p.duration, p.dummy.mass, float(p.std.max()))) if feasible else None
    return best, plans


__all__ = ["CG_MODEL_CHECKS", "CG_RESULT_SCHEMA", "CG_RESULT_SCHEMA_VERSION", "CG_RESULT_UNITS", "CG_VERDICTS",
           "DEFAULT_ANCHOR_STD", "DEFAULT_DUMMY_POSITION_STD", "DEFAULT_LENGTH_STD", "VALIDATION_SIGMA", "CgOptions", "CgPlan", "CgResult", "CgValidation", "SensorNoise", "StatePose", "StaticState",
           "StaticsError", "StreamStats", "candidate_positions", "estimate_cg", "plan_static_test",
           "predict_cg_std", "static_equilibrium"]
