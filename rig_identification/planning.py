"""Know before you shake: predicted inertia uncertainty of a planned run, and experiment design.

The prediction of a run's σ is :mod:`.propagation`'s (:func:`~.propagation.predict_from_trajectory`).

Design
------
:func:`plan_experiment` searches the exciter frequency, mounting point (corners of the box
spanned by the body anchors and the rig's exciter position), spin axis (body x, y, z or a
diagonal between two of them, :data:`SPIN_AXES`), sense of rotation and force amplitude: a fast screen of the linearised rig (:func:`linear_rig`)
driven from rest by the spinning-up force and the stationary form of the noise model, then
simulations of the best candidates with the full predictor; the amplitude is the largest for
which the simulated run keeps every cable above ``min_tension_ratio`` of its static tension,
the rotation (start-up included) below ``max_rotation_deg``, the force below ``max_force``
and the swing from growing.  Frequencies near a mode, its double or a sum of two modes are
skipped (:func:`resonances`).  A single steady harmonic cannot determine all six entries
(the body's angular velocity then stays in one plane: the moment of inertia about its normal
is seen only through the start-up transients), so a second run — complementary, or the same
again — is added when allowed; it may also use another cable geometry (``geometries``: the
lab's own, or :func:`geometry_variants`, the ceiling anchors moved), which changes the modes
and so the directions the rig moves in.  Pairs are ranked on short simulations and the best
few confirmed by full-length ones before one is chosen.  Objective: ``"baseline"`` (the least-improved entry as much
better than a baseline run as possible) or ``"relative"`` (the largest σ relative to the
entry: diagonals to themselves, products to the largest diagonal).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.signal import butter, sosfreqz
from scipy.spatial.transform import Rotation

from .experiment import DEFAULT_STIFFNESS
from .identification import KEYS, basis, physically_consistent, to_tensor
from .propagation import (REFERENCE_NOISE, REFERENCE_RATES, PlanError, Prediction, Trajectory, channel_sigmas,
                          combine, predict_from_trajectory, stationary_e_response, tracker_model, wrench_jacobians)
from .rig import Rig

_DIAGONALS = {"x+y": (1, 1, 0), "x-y": (1, -1, 0), "x+z": (1, 0, 1), "x-z": (1, 0, -1), "y+z": (0, 1, 1),
              "y-z": (0, 1, -1)}


def _spin_rpy(v) -> tuple:
    """Exciter rpy (extrinsic xyz, rad) whose z axis is the body-frame direction ``v``."""
    v = np.asarray(v, float) / np.linalg.norm(v)
    R, _ = Rotation.align_vectors([v], [[0.0, 0.0, 1.0]])
    return tuple(float(a) for a in R.as_euler("xyz"))


SPIN_AXES = {"x": (0.0, math.pi / 2, 0.0), "y": (-math.pi / 2, 0.0, 0.0), "z": (0.0, 0.0, 0.0),
             **{k: _spin_rpy(v) for k, v in _DIAGONALS.items()}}
"""Exciter rpy (body -> exciter frame) whose z axis (the spin axis) is body x, y, z or the
diagonal between two of them ("x+y": along (1, 1, 0)/√2, "x-y": along (1, −1, 0)/√2, …).
A diagonal axis turns the force in a plane that holds one body axis and the other two's
diagonal: on the thesis rig it drives roll and pitch in phase, which the products of
inertia need (case 16: Ixy's σ 3.1× below the thesis excitation's, against 2.8× with the
body axes alone)."""


# --- the linear noise model --------------------------------------------------------------

# --- experiment design --------------------------------------------------------------------

@dataclass(frozen=True)
class Run:
    """One planned exciter run: rotating force ``amplitude`` N at ``frequency`` Hz, acting at
    ``position`` (3,) body frame m, spinning about body ``spin_axis`` (a key of :data:`SPIN_AXES`),
    for ``duration`` s (spin-up ramp ``ramp_time`` s, as the reference simulator)."""

    frequency: float
    amplitude: float
    position: tuple
    spin_axis: str
    duration: float = 120.0
    ramp_time: float = 2.0
    rpy: tuple | None = None    # exciter rpy if not one of SPIN_AXES (e.g. the rig's own)
    direction: int = 1          # sense of rotation about the spin axis (+1: x toward y of the exciter frame)

    @property
    def exciter_rpy(self) -> tuple:
        return tuple(self.rpy) if self.rpy is not None else SPIN_AXES[self.spin_axis]

    def to_dict(self) -> dict:
        return {"frequency_hz": float(self.frequency), "amplitude_n": float(self.amplitude),
                "exciter_position_body_m": [float(x) for x in self.position], "spin_axis_body": self.spin_axis,
                "spin_axis_unit_body": [round(float(x), 6) + 0.0 for x in
                                        Rotation.from_euler("xyz", self.exciter_rpy).apply([0, 0, 1])],
                "exciter_rpy": [float(x) for x in self.exciter_rpy], "direction": int(self.direction),
                "duration_s": float(self.duration),
                "ramp_time_s": float(self.ramp_time), "ramp_shape": "spin_up"}


@dataclass
class Body:
    """The rig and the nominal body: rig (CG from rig.yaml), mass kg, inertia (3,3) kg·m²
    about the CG, body axes; cable stiffness (N,) N/m of the simulation (rig.yaml's, else
    the simulator's 5e6); rates Hz and noise σ of the sensors."""

    rig: Rig
    mass: float
    inertia: np.ndarray
    stiffness: np.ndarray
    rates: dict
    noise: dict

    def experiment(self, run: Run, seed: int = 0):
        """The noise-free :class:`~.simulator.Experiment` of ``run``."""
        from .simulator import experiment_from_dict, inertia_entries
        rig = self.rig.to_dict()
        rig.pop("dummy_mass", None)
        rig["body"]["mass"] = float(self.mass)
        rig["body"]["center_of_gravity"] = [float(x) for x in self.rig.require_cg()]
        rig["exciter"] = {"position": [float(x) for x in run.position], "rpy": [float(x) for x in run.exciter_rpy]}
        d = {"name": "plan", "rig": rig, "inertia_about_cg": inertia_entries(self.inertia),
             "cable_model": {"type": "spring", "stiffness": [float(k) for k in self.stiffness]},
             "initial": {"equilibrium": True},
             "excitation": {"rotating": {"amplitude": float(run.amplitude), "frequency": float(run.frequency),
                                         "ramp_time": float(run.ramp_time), "ramp_shape": "spin_up", "phase": 0.0,
                                         "direction": int(run.direction), "start_time": 0.0}},
             "duration": float(run.duration),
             "sensors": {"rates_hz": dict(self.rates), "noise": {k: 0.0 for k in REFERENCE_NOISE}},
             "seed": seed}
        return experiment_from_dict(d, "planned run")


@dataclass
class LinearRig:
    """The rig linearised about its static equilibrium (coordinates q = [dp_cg (3, world, m),
    φ (3, world rotation, rad)]): mass M, stiffness K, cable damping C (6,6); length
    Jacobian G (N,6); static tensions T0 (N,) N; cable stiffness k and damping c (N,);
    equilibrium origin position (3,) and rotation R0 (3,3) body -> world."""

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    G: np.ndarray
    T0: np.ndarray
    k: np.ndarray
    c: np.ndarray
    position: np.ndarray
    R0: np.ndarray
    cg: np.ndarray


def linear_rig(body: Body) -> LinearRig:
    """Linearise the spring-cable rig about its equilibrium (as :func:`~.modes.natural_modes`,
    plus the cables' damping), for the steady-state response of the design screen."""
    from .modes import gradients, length_fn, length_hessians
    from .simulator import CableModel, equilibrium
    rig = body.rig
    cg = rig.require_cg()
    cm = CableModel.spring(rig, body.mass, stiffness=body.stiffness)
    pos, R0, T = equilibrium(rig, body.mass, cg, cm)
    p_cg = pos + R0.apply(cg)
    R = R0.as_matrix()
    M = np.zeros((6, 6))
    M[:3, :3] = body.mass * np.eye(3)
    M[3:, 3:] = R @ body.inertia @ R.T
    G, _ = gradients(rig, p_cg, R0, cg)
    H = length_hessians(length_fn(rig, p_cg, R0, cg), len(rig.cables))
    taut = T > 0
    K = np.einsum("i,iab->ab", T, H) + np.einsum("i,ia,ib->ab", cm.stiffness * taut, G, G)
    C = np.einsum("i,ia,ib->ab", cm.damping * taut, G, G)
    return LinearRig(M, 0.5 * (K + K.T), C, G, T, cm.stiffness, cm.damping, pos, R, cg)


def _spin_up(f: float, t: np.ndarray, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """cos θ and sin θ times the amplitude factor of a unit rotating force with a spin-up
    ramp (as :class:`~.simulator.RotatingForce` with ramp_shape spin_up, direction +1)."""
    t = np.asarray(t, float)
    if ramp > 0:
        amp = np.where(t < ramp, (t / ramp) ** 2, 1.0)
        th = np.where(t < ramp, np.pi * f * t**2 / ramp, 2 * np.pi * f * (t - ramp / 2))
    else:
        amp, th = np.ones_like(t), 2 * np.pi * f * t
    return amp * np.cos(th), amp * np.sin(th)


class _Screen:
    """Fast design screen: the linearised rig (:func:`linear_rig`) driven by the rotating
    force from rest (spin-up, transients and steady state), sampled at ``fs_screen``, and
    the stationary form of the noise model (no filter edges, time-averaged sensitivities)."""

    def __init__(self, body: Body, lin: LinearRig, duration: float, settle: float, ramp: float = 2.0,
                 fs_screen: float = 50.0, tracker_params: dict | None = None):
        from scipy.linalg import expm
        self.body, self.lin, self.duration, self.settle, self.ramp = body, lin, duration, settle, ramp
        rig = body.rig
        self.fs = float(body.rates["imu"])
        self.fss = fs_screen
        self.t = np.arange(int(round(duration * fs_screen)) + 1) / fs_screen
        self.win = self.t >= settle
        Mi = np.linalg.inv(lin.M)
        A = np.zeros((12, 12))
        A[:6, 6:] = np.eye(6)
        A[6:, :6] = -Mi @ lin.K
        A[6:, 6:] = -Mi @ lin.C
        Z = np.zeros((18, 18))
        Z[:12, :12] = A
        Z[6:12, 12:] = Mi
        Ed = expm(Z / fs_screen)
        self.Ad, self.Bd = Ed[:12, :12], Ed[:12, 12:]
        self.D = wrench_jacobians(rig, lin.position[None], lin.R0[None], lin.T0[None], None)
        self.D = (self.D[0], self.D[1], self.D[2], np.zeros((1, 3, 2)))
        self.tm = tracker_model(rig, lin.position, lin.R0, tracker_params)
        self.P = np.linalg.inv(body.inertia)
        sig, _ = channel_sigmas(body.noise, body.rates, self.fs, len(rig.cables), rig.inclinometer is not None)
        self.sig = sig[:8 + len(rig.cables)]
        self.R_imu = rig.imu.rotation.as_matrix()

    def responses(self, f: float) -> np.ndarray:
        """(n_t, 12, 2, 6) state response to unit wrench components driven by cos θ (…, 0, j)
        and sin θ (…, 1, j) of a unit rotating force at f Hz."""
        c, s = _spin_up(f, self.t, self.ramp)
        n = len(self.t)
        X = np.zeros((n, 12, 2, 6))
        x = np.zeros((12, 2, 6))
        Bd = self.Bd
        for i in range(1, n):
            u_c, u_s = c[i - 1], s[i - 1]
            x = np.einsum("ij,jab->iab", self.Ad, x)
            x[:, 0, :] += Bd * u_c
            x[:, 1, :] += Bd * u_s
            X[i] = x
        return X

    def band(self, f: float, rot_f) -> tuple[float, float]:
        return recommended_band(f, rot_f, self.duration - self.settle, self.fs)

    def noise_density(self, band) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per-sample (fs) residual density S (K,3,3) on the screen's rfft grid, the filter's
        |F|² there, and the per-axis residual variance (3,)."""
        nw = int(self.win.sum())
        f = np.fft.rfftfreq(nw, 1 / self.fss)
        sos = butter(4, band, btype="bandpass", fs=self.fs, output="sos")
        H = stationary_e_response(self.tm, self.D, self.P, sos, self.fs, f, self.R_imu)[:, :, :len(self.sig)]
        S = np.einsum("kad,d,kbd->kab", H, self.sig**2, H.conj())
        _, hf = sosfreqz(sos, worN=f, fs=self.fs)
        fg = np.linspace(band[0] * 0.3, min(band[1] * 3, 0.45 * self.fs), 600)
        Hg = stationary_e_response(self.tm, self.D, self.P, sos, self.fs, fg, self.R_imu)[:, :, :len(self.sig)]
        var = 2 * np.trapezoid(np.einsum("kad,d,kad->ka", Hg, self.sig**2, Hg.conj()).real, fg, axis=0) / self.fs
        return S, np.abs(hf) ** 2, var

    def candidate(self, X: np.ndarray, position, rpy, limits: dict, noise_dens, band, amplitude=None,
                  direction: int = 1):
        """Amplitude within the limits and the screen prediction for one mounting.
        Returns (amplitude N, binding limit, peak rotation deg, min tension ratio, Prediction)."""
        lin = self.lin
        Re = Rotation.from_euler("xyz", rpy).as_matrix()[:, :2]
        Fw = lin.R0 @ Re
        r = lin.R0 @ (np.asarray(position, float) - lin.cg)
        L = np.vstack([Fw, np.cross(r, Fw.T).T]) * np.array([1.0, float(direction)])   # (6,2) per (cos, sin)
        x = np.einsum("nicj,jc->ni", X, L)                             # (n,12) per newton
        phi = x[:, 3:6]
        rot_unit = float(np.max(np.linalg.norm(phi, axis=1)))
        dT = (lin.k * (x[:, :6] @ lin.G.T)) + lin.c * (x[:, 6:] @ lin.G.T)
        drop_unit = float(np.max(-dT / lin.T0[None, :]))
        lim = {"force": limits["max_force_n"],
               "rotation": np.radians(limits["max_rotation_deg"]) / max(rot_unit, 1e-300),
               "tension": (1 - limits["min_tension_ratio"]) / max(drop_unit, 1e-300)}
        key = min(lim, key=lim.get)
        amp = 0.95 * lim[key] if key != "force" else lim[key]
        if amplitude is not None:
            amp, key = float(amplitude), "given"
        omega = (x[self.win, 9:12] @ lin.R0) * amp                     # body rate (n,3)
        return amp, key, np.degrees(rot_unit * amp), 1 - drop_unit * amp, self.predict(omega, noise_dens, band)

    def predict(self, omega: np.ndarray, noise_dens, band) -> Prediction | None:
        """Screen prediction for the body rate ``omega`` (n,3) rad/s, body axes, sampled at
        the screen's rate over the fitted window."""
        S, F2, var = noise_dens
        nw = len(omega)
        Om = np.fft.rfft(omega, axis=0)                                # (K,3)
        E = basis()
        Ah = -F2[:, None, None] * np.einsum("ij,kjl,fl->fik", self.P, E, Om)   # (K,3,6)
        mult = np.full(len(Om), 2.0)
        mult[0] = 1.0
        if nw % 2 == 0:
            mult[-1] = 1.0
        scale = (self.fs / self.fss) / nw
        axis_bread = scale * np.einsum("f,fak,fal->akl", mult, Ah.conj(), Ah).real
        axis_meat = scale * np.einsum("f,fak,fab,fbl->abkl", mult, Ah.conj(), S, Ah).real
        white = axis_bread.sum(0)
        white_meat = scale * self.body.noise["gyro"] ** 2 * np.einsum("f,f,fak,fal->kl", mult, F2**2, Ah.conj(),
                                                                      Ah).real
        rot_rms = np.sqrt(np.mean(np.fft.irfft(Om * F2[:, None], n=nw, axis=0) ** 2, axis=0))
        try:
            return Prediction.assemble(self.body.inertia, axis_bread, {"noise": axis_meat}, white, white_meat, var,
                                       band, self.duration - self.settle, int(nw * self.fs / self.fss), rot_rms)
        except np.linalg.LinAlgError:
            return None


@dataclass
class Candidate:
    """A screened run: the run, its (screen or simulated) prediction, the binding limit."""

    run: Run
    prediction: Prediction
    limit: str
    simulated: bool = False
    peak_rotation_deg: float | None = None
    min_tension_ratio: float | None = None
    band: tuple | None = None      # identification band to use (None: the identifier's automatic band)
    geometry: str | None = None    # None: the rig's own cables; else the other cable geometry's label
    body: "Body | None" = None     # the body on that geometry (None: the plan's)

    def to_dict(self) -> dict:
        geo = None
        if self.geometry is not None and self.body is not None:
            geo = {"label": self.geometry,
                   "cables": [{"name": c.name, "ceiling_anchor": [float(x) for x in c.ceiling_anchor],
                               "body_anchor": [float(x) for x in c.body_anchor], "length": float(c.length)}
                              for c in self.body.rig.cables]}
        return {"run": self.run.to_dict(), "cable_geometry": geo, "limit": self.limit, "simulated": self.simulated,
                "identification_band_hz": None if self.band is None else [float(x) for x in self.band],
                "peak_rotation_deg": self.peak_rotation_deg, "min_tension_ratio": self.min_tension_ratio,
                "prediction": self.prediction.to_dict()}


@dataclass
class Plan:
    """The recommended runs, their joint prediction, the baseline for comparison, the rig's
    modes and the limits used."""

    runs: list[Candidate]
    prediction: Prediction
    baseline: Candidate
    modes: list
    limits: dict
    notes: list[str] = field(default_factory=list)
    other_geometries: list = field(default_factory=list)   # per other cable geometry: its best second run

    def improvement(self) -> np.ndarray:
        """(6,) baseline σ / plan σ per entry."""
        return self.baseline.prediction.std / self.prediction.std

    def to_dict(self) -> dict:
        return {"modes": [m.to_dict() for m in self.modes],
                "runs": [c.to_dict() for c in self.runs],
                "prediction": self.prediction.to_dict(),
                "baseline": self.baseline.to_dict(),
                "improvement": {k: float(v) for k, v in zip(KEYS, self.improvement())},
                "limits": dict(self.limits), "notes": list(self.notes),
                "other_geometries": [c.to_dict() for c in self.other_geometries]}


def candidate_positions(rig: Rig) -> list[np.ndarray]:
    """Mounting points: the corners of the box spanned by the body anchors and the rig's
    exciter position (body frame, m); a flat box (all anchors at one height, no exciter)
    keeps its two faces at the anchors' height and at the CG's."""
    pts = [*rig.body_anchors]
    if rig.exciter is not None:
        pts.append(rig.exciter.position)
    pts.append(rig.require_cg())
    pts = np.array(pts)
    lo, hi = pts.min(0), pts.max(0)
    return [np.array([x, y, z]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]


def recommended_band(f0: float, rot_f, duration: float, fs: float) -> tuple[float, float]:
    """Pass band (Hz) around the exciter frequency ``f0`` and the rotational modes below 5 Hz
    (``rot_f``), widened like :func:`~.identification.auto_band` (0.6x below, 1.5x above)."""
    fr = [f0] + [x for x in rot_f if x < 5.0]
    return (max(0.15, 0.6 * min(fr), 2.0 / duration), min(1.5 * max(fr), 0.4 * fs))


def _sim_check(body: Body, run: Run, limits: dict, settle: float, tracker_params,
               rot_f=None) -> tuple[Candidate, object]:
    """Simulate ``run`` without noise, measure its peak rotation, lowest tension ratio and
    whether the swing keeps growing (last third against the middle third), and predict.
    Returns (Candidate, SimResult)."""
    from .simulator import simulate
    sim = simulate(body.experiment(run))
    rot = sim.states.rotation
    ang = np.linalg.norm((rot * rot[0].inv()).as_rotvec(), axis=1)
    peak = float(np.degrees(np.max(ang)))
    T = sim.states.tensions
    tmin = float(np.min(T / T[0][None, :]))
    n = len(ang)
    growing = bool(np.max(ang[2 * n // 3:]) > 1.15 * np.max(ang[n // 3: 2 * n // 3]))
    try:
        traj = Trajectory.from_simulation(sim)
    except PlanError:   # slack cables etc. leave too little to fit: scale down (see _fit_amplitude)
        cand = Candidate(run, None, "", True, peak, tmin)
        cand.growing = growing
        return cand, sim
    pred = predict_from_trajectory(traj, body.noise, settle, None, tracker_params)
    band = None
    if rot_f is not None:
        # the identifier's automatic band also takes in the weak difference tones of large
        # swings (f0 - f_mode), where the tracker's noise is large; a band around the exciter
        # and the rotational modes may do better: recommend it then
        rec = recommended_band(run.frequency, rot_f, traj.t[-1] - traj.t[0] - settle, float(body.rates["imu"]))
        pr = predict_from_trajectory(traj, body.noise, settle, rec, tracker_params)
        if pr.objective < 0.9 * pred.objective:
            pred, band = pr, rec
    cand = Candidate(run, pred, "", True, peak, tmin, band)
    cand.growing = growing
    return cand, sim


def _feasible(c: Candidate, limits: dict) -> bool:
    return (c.prediction is not None and c.peak_rotation_deg <= limits["max_rotation_deg"] * 1.001
            and c.min_tension_ratio >= limits["min_tension_ratio"] * 0.999 and not getattr(c, "growing", False))


def _fit_amplitude(body: Body, run: Run, limits: dict, settle: float, tracker_params, limit: str,
                   tries: int = 2, grow: bool = True, rot_f=None) -> Candidate | None:
    """Simulate ``run`` and bring its force amplitude to the limits: scale it linearly so
    that the simulated peak rotation and lowest tension (start-up transients and beats
    included) meet them with a 3 % margin, at most ``limits["max_force_n"]`` (up only if
    ``grow``), and simulate again.  None if the run still breaks a limit or its swing keeps
    growing (a parametric resonance)."""
    cand, _ = _sim_check(body, run, limits, settle, tracker_params, rot_f)
    for _ in range(tries):
        if getattr(cand, "growing", False):
            return None
        s_rot = np.radians(limits["max_rotation_deg"]) / max(np.radians(cand.peak_rotation_deg), 1e-12)
        s_ten = (1 - limits["min_tension_ratio"]) / max(1 - cand.min_tension_ratio, 1e-12)
        s_force = limits["max_force_n"] / run.amplitude
        s = min(s_rot, s_ten)
        if s >= 1.0:
            s = min(0.97 * s, s_force) if grow else 1.0
            if s < 1.05:
                break
        else:
            s *= 0.97
        run = replace(run, amplitude=run.amplitude * s)
        cand, _ = _sim_check(body, run, limits, settle, tracker_params, rot_f)
        grow = False
    if not _feasible(cand, limits):
        return None
    use = {"rotation": cand.peak_rotation_deg / limits["max_rotation_deg"],
           "tension": (1 - cand.min_tension_ratio) / (1 - limits["min_tension_ratio"]),
           "force": run.amplitude / limits["max_force_n"]}
    cand.limit = max(use, key=use.get)   # the limit it comes closest to
    return cand


def amplitude_at_limits(body: Body, run: Run, max_rotation_deg: float = 3.0, min_tension_ratio: float = 0.2,
                        max_force: float = math.inf, settle: float = 5.0) -> Candidate | None:
    """``run`` (its frequency, exciter position and spin axis kept) at the largest force
    amplitude within the limits of :func:`plan_experiment` (same defaults): peak rotation ≤
    ``max_rotation_deg``, every cable ≥ ``min_tension_ratio`` × its static tension (start-up
    and beats included, 3 % margin), force ≤ ``max_force`` N; found by noise-free
    simulation as the planner does (:func:`_fit_amplitude`).  Returns the
    :class:`Candidate` (``.run.amplitude`` N, ``.peak_rotation_deg``,
    ``.min_tension_ratio``, ``.prediction``), or None if no amplitude keeps the run within
    the limits (its swing keeps growing).  Raises :class:`PlanError` for bad limits,
    :class:`~.simulator.SimulationError`."""
    return _fit_amplitude(body, run, _limits(max_force, max_rotation_deg, min_tension_ratio), settle, None, "")


def _limits(max_force: float, max_rotation_deg: float, min_tension_ratio: float) -> dict:
    """The run limits of :func:`plan_experiment` as a mapping.  Raises :class:`PlanError`."""
    if not (0 <= min_tension_ratio < 1) or not max_rotation_deg > 0 or not max_force > 0:
        raise PlanError("limits: need 0 ≤ min tension ratio < 1, max rotation > 0, max force > 0")
    return {"max_force_n": max_force, "max_rotation_deg": max_rotation_deg, "min_tension_ratio": min_tension_ratio}


def plan_experiment(body: Body, baseline: Run, duration: float = 120.0, max_force: float = math.inf,
                    max_rotation_deg: float = 3.0, min_tension_ratio: float = 0.2,
                    frequencies: tuple[float, float] = (0.3, 4.0), positions: list | None = None,
                    max_runs: int = 2, objective: str = "baseline", refine: int = 3, settle: float = 5.0,
                    short: float = 30.0, mode_margin: float = 0.1, tracker_params: dict | None = None,
                    geometries: list | None = None, progress=None) -> Plan:
    """Recommend one or two exciter runs (see module docstring).

    body: :class:`Body`.  baseline: the run to compare with (e.g. the thesis's 200 N at
    1.05 Hz at the rig's exciter).  objective: ``"baseline"`` — make the least-improved
    entry as much better than the baseline as possible (minimise max_k σ_k / σ_k,baseline),
    or ``"relative"`` — minimise the largest relative σ (diagonals relative to themselves,
    products to the largest diagonal).  Limits: force amplitude ≤ ``max_force`` N, body
    rotation ≤ ``max_rotation_deg`` (peak, start-up included), every cable ≥
    ``min_tension_ratio`` × its static tension, no growing swing; exciter frequencies in
    ``frequencies`` Hz and at least ``mode_margin`` (relative) away from every natural
    frequency, its double and every pairwise sum (:func:`resonances`).  positions:
    candidate mounting points (body m; default :func:`candidate_positions`).  max_runs: 1
    or 2.  refine: how many screened candidates are simulated (``short`` s each).
    geometries: other cable geometries the rig can take for the second run, [(label,
    :class:`~.rig.Rig`)] with the same body (e.g. :func:`geometry_variants`); the best runs
    on each are searched like the rig's own and paired with the best run on the rig.
    progress: optional callable(str) for status lines.
    Raises :class:`PlanError`, :class:`~.simulator.SimulationError`.
    """
    from .modes import natural_modes
    from .simulator import SimulationError
    say = progress or (lambda s: None)
    limits = _limits(max_force, max_rotation_deg, min_tension_ratio)
    if not 0 < frequencies[0] < frequencies[1]:
        raise PlanError(f"frequency range {frequencies} Hz must be 0 < low < high")
    if objective not in ("baseline", "relative"):
        raise PlanError(f"objective {objective!r}: baseline or relative")
    if not duration > settle + 10.0:
        raise PlanError(f"--duration {duration:g} s: runs must last more than {settle + 10:g} s")
    short = min(short, duration)
    limits.update({"duration_s": duration, "frequency_range_hz": list(frequencies), "mode_margin": mode_margin,
                   "objective": objective})
    rig = body.rig
    modes = natural_modes(rig, body.mass, rig.require_cg(), body.inertia, body.stiffness)
    rot_f = _rotational(modes)
    rot_fs = {None: rot_f}   # per cable geometry: its rotational modes (Hz), for the identification band
    screen = _Screen(body, linear_rig(body), duration, settle, tracker_params=tracker_params)
    # --- the baseline, simulated in full and screened (each stage compares like with like)
    say(f"simulating the baseline ({baseline.amplitude:.0f} N at {baseline.frequency:.2f} Hz, {duration:.0f} s) ...")
    base, _ = _sim_check(body, replace(baseline, duration=duration), limits, settle, tracker_params)
    base.limit = "baseline"
    if base.prediction is None:
        raise PlanError(f"the baseline excitation ({baseline.amplitude:g} N at {baseline.frequency:g} Hz) slackens "
                        "cables so often that the identifier could not fit it; choose a gentler --baseline-force")
    bband = screen.band(baseline.frequency, rot_f)
    base_screen = screen.candidate(screen.responses(baseline.frequency), baseline.position, baseline.exciter_rpy,
                                   limits, screen.noise_density(bband), bband, baseline.amplitude)[4]
    if objective == "baseline":
        ref_screen = base_screen.std if base_screen is not None else base.prediction.std
        ref_sim = base.prediction.std
    else:
        ref_screen = ref_sim = base.prediction.scale
    done: dict = {}

    def search(b: Body, label: str | None, scr: _Screen | None = None, partner: Candidate | None = None):
        """Screen frequencies, mounting points and spin axes on the body ``b`` (cable
        geometry ``label``; None: the rig's own), then simulate the best distinct
        ``refine`` of them (``short`` s, amplitude brought to the limits): best alone and,
        with ``partner`` given, also best together with that run (a second run).  Returns
        (screened, simulated singles)."""
        where = "" if label is None else f" ({label})"
        ms = modes if label is None else natural_modes(b.rig, b.mass, b.rig.require_cg(), b.inertia, b.stiffness)
        mf = np.array([m.frequency for m in ms])
        rf = rot_fs.setdefault(label, _rotational(ms))
        scr = scr or _Screen(b, linear_rig(b), duration, settle, tracker_params=tracker_params)
        say(f"screening frequencies, mounting points and spin axes (linearised rig{where}) ...")
        avoid = resonances(mf)
        freqs = [f for f in np.geomspace(frequencies[0], frequencies[1], 30)
                 if np.all(np.abs(f / avoid - 1) >= mode_margin)]
        if not freqs:
            raise PlanError(f"no exciter frequency in {frequencies[0]:g}–{frequencies[1]:g} Hz is {100 * mode_margin:.0f} % "
                            f"away from the rig's modes{where} ({', '.join(f'{f:.2f}' for f in mf)} Hz), their doubles "
                            "and their pairwise sums")
        pts = [np.asarray(p, float) for p in (positions if positions else candidate_positions(b.rig))]
        screened: list[Candidate] = []
        for f in freqs:
            X = scr.responses(f)
            band = scr.band(f, rf)
            dens = scr.noise_density(band)
            for p in pts:
                for ax in SPIN_AXES:
                    for sense in (1, -1):
                        amp, lim, rot, tmin, pred = scr.candidate(X, p, SPIN_AXES[ax], limits, dens, band,
                                                                  direction=sense)
                        if pred is None or not np.all(np.isfinite(pred.std)):
                            continue
                        screened.append(Candidate(Run(float(f), float(amp), tuple(float(x) for x in p), ax, duration,
                                                      direction=sense), pred, lim, False, float(rot), float(tmin),
                                                  geometry=label, body=b))
        screened.sort(key=lambda c: c.prediction.worst(ref_screen))
        picks = _distinct(screened, refine)
        if partner is not None:   # a ranking only: the partner's prediction is simulated, the candidates' screened
            together = sorted(screened, key=lambda c: combine([partner.prediction, c.prediction]).worst(ref_sim))
            picks += [c for c in _distinct(together, refine) if all(not _same(c, o) for o in picks)]
        singles = [x for x in (simulate_short(c, "a candidate run") for c in picks) if x is not None]
        return screened, singles

    def simulate_short(c: Candidate, what: str) -> Candidate | None:
        key = _run_key(c)
        if key not in done:
            where = "" if c.geometry is None else f" ({c.geometry})"
            say(f"simulating {what}{where}: {c.run.frequency:.2f} Hz, {c.run.amplitude:.0f} N, spin axis "
                f"{c.run.spin_axis}, at {np.round(c.run.position, 2).tolist()} m ({short:.0f} s) ...")
            cs = _fit_amplitude(c.body, replace(c.run, duration=short), limits, settle, tracker_params, c.limit,
                                rot_f=rot_fs[c.geometry])
            if cs is not None:
                cs.prediction = cs.prediction.scaled((duration - settle) / cs.prediction.duration)
                cs.geometry, cs.body = c.geometry, c.body
            done[key] = cs
        return done[key]

    def worst(*cs: Candidate) -> float:
        return combine([c.prediction for c in cs]).worst(ref_sim)

    screened, singles = search(body, None, screen)
    if not screened:
        raise PlanError("no candidate run moves the body measurably")
    if not singles:
        raise PlanError("every screened candidate broke a limit in simulation (cable slack, rotation, growing "
                        "swing): lower --max-force or change the frequency range")
    singles.sort(key=worst)
    full: dict = {}

    def simulate_full(c: Candidate, what: str) -> Candidate | None:
        """``c`` simulated over the whole ``duration``, its amplitude brought to the limits
        again (a run can break a limit late: beats, slow growth).  None if it cannot."""
        key = _run_key(c)
        if key not in full:
            if short >= duration:   # already simulated in full
                full[key] = c
                return c
            where = "" if c.geometry is None else f" on cable geometry {c.geometry!r}"
            say(f"simulating {what}{where} in full ({c.run.frequency:.2f} Hz, {duration:.0f} s) ...")
            cf = _fit_amplitude(c.body, replace(c.run, duration=duration), limits, settle, tracker_params, c.limit,
                                rot_f=rot_fs[c.geometry])
            if cf is not None:
                cf.geometry, cf.body = c.geometry, c.body
            full[key] = cf
        return full[key]

    # --- the best single run, confirmed in full (falling back on the next if it breaks a limit late)
    first = None
    for n_c, c in enumerate(singles):
        first = simulate_full(c, "the best run" if n_c == 0 else "the next candidate")
        if first is not None:
            break
    if first is None:
        raise PlanError(f"every candidate run broke a limit over {duration:.0f} s in simulation (cable slack, "
                        "rotation, growing swing); lower --max-force or change the frequency range")
    chosen = [first]
    notes: list[str] = []
    others: list[Candidate] = []
    if max_runs >= 2:
        sims2 = []
        for a, b in _best_pairs(screened, max(2, refine // 2), ref_screen):
            sa, sb = simulate_short(a, "a pair, first run"), simulate_short(b, "a pair, second run")
            if sa is not None and sb is not None:
                sims2.append((sa, sb))
        sims2 += [(x, y) for k, x in enumerate(singles) for y in singles[k + 1:]]
        g_best: dict = {}
        for label, grig in (geometries or []):
            if len(grig.cables) != len(rig.cables):
                notes.append(f"cable geometry {label!r} not usable: {len(grig.cables)} cables, the rig has "
                             f"{len(rig.cables)}")
                continue
            try:
                gb = replace(body, rig=replace(grig, mass=body.mass, center_of_gravity=rig.require_cg()))
                _, gs = search(gb, label, partner=singles[0])
            except (PlanError, SimulationError) as e:
                notes.append(f"cable geometry {label!r} not usable: {e}")
                continue
            if not gs:
                notes.append(f"cable geometry {label!r}: every candidate run broke a limit in simulation")
            sims2 += [(singles[0], y) for y in gs]
            if gs:
                g_best[label] = min(gs, key=lambda y: worst(singles[0], y))
        # the short runs' predictions, scaled to the full length, only rank the pairs (beats and
        # start-up weigh differently in 30 s): the best few that promise to beat the best run done
        # twice are simulated in full and compared in full
        repeat_short = worst(singles[0]) / math.sqrt(2)
        promising = [ab for ab in sorted(sims2, key=lambda ab: worst(*ab)) if worst(*ab) < repeat_short][:3]
        repeat = worst(first) / math.sqrt(2)
        best, best_val = None, repeat
        for a, b in promising:
            fa, fb = simulate_full(a, "a pair's first run"), simulate_full(b, "a pair's second run")
            if fa is not None and fb is not None and worst(fa, fb) < best_val:
                best, best_val = (fa, fb), worst(fa, fb)
            # a run simulated in full for a pair may itself be the better run to do twice than the
            # best screened single (with 20 s runs a pair's first run twice gave 0.306 of the
            # reference σ, the pair 0.388, the best single twice more)
            for f in (fa, fb):
                if f is not None and worst(f, f) < best_val:
                    best, best_val = (f, f), worst(f, f)
        if best is not None and best[0] is best[1]:
            chosen = list(best)
            notes.append(f"a run simulated as part of a pair, done twice: worst entry σ/reference {best_val:.3g}, "
                         f"against {repeat:.3g} for the best screened run done twice")
        elif best is not None:
            chosen = list(best)
            other = "" if best[1].geometry is None else f" (the second on cable geometry {best[1].geometry!r})"
            notes.append(f"two complementary runs{other}: worst entry σ/reference {best_val:.3g}, against "
                         f"{repeat:.3g} for the best run done twice and {worst(first):.3g} for it alone")
        else:
            chosen = [first, first]
            notes.append(f"no other run complements the best one better than itself: do it twice (every σ / √2; "
                         f"worst entry σ/reference {repeat:.3g} against {worst(first):.3g} for one run)")
        for label, y in g_best.items():   # what each other geometry offered (full-length where simulated so)
            key = _run_key(y)
            yf = full.get(key)
            others.append(yf if yf is not None else y)
            how = ("full-length simulation" if yf is not None else
                   "short simulation; it broke a limit over the full length" if key in full else "short simulation")
            notes.append(f"cable geometry {label!r}: its best second run, {others[-1].run.amplitude:.0f} N at "
                         f"{others[-1].run.frequency:.2f} Hz, gives worst entry σ/reference "
                         f"{worst(first, others[-1]):.3g} with the best run ({how})")
    return Plan(chosen, combine([c.prediction for c in chosen]), base, modes, limits, notes, others)


def geometry_variants(body: Body, shift: float = 1.0) -> list[tuple[str, Rig]]:
    """Other cable geometries for a second run: the ceiling anchors moved ``shift`` m
    farther apart (and, where they stay more than 0.2 m outside the body anchors, closer
    together) along world x, and along world y — each anchor away from (toward) the
    anchors' mid-point on that axis — with every cable length re-set to the anchors'
    distance at the rig's own equilibrium pose (cables of the same material: the
    stiffness is kept).  The body settles near that pose: the new cable directions
    balance its weight at a slightly different one (on the thesis rig within 5 cm and
    3°).  A variant whose cables would lean inward is left out.  Returns [(label, Rig)]."""
    from .simulator import CableModel, equilibrium
    rig = body.rig
    cm = CableModel.spring(rig, body.mass, stiffness=body.stiffness)
    pos, R0, _ = equilibrium(rig, body.mass, rig.require_cg(), cm)
    B = pos + R0.apply(rig.body_anchors)                     # body anchors in world at equilibrium
    A = np.asarray(rig.ceiling_anchors, float)
    out = []
    for ax, name in ((0, "x"), (1, "y")):
        mid = 0.5 * (A[:, ax].min() + A[:, ax].max())
        side = np.sign(A[:, ax] - mid)
        for sense, word in ((1, "farther apart"), (-1, "closer together")):
            A2 = A.copy()
            A2[:, ax] += sense * shift * side
            if sense < 0 and np.any(side * (A2[:, ax] - B[:, ax]) < 0.2):
                continue        # the cables would lean inward: another rig, not a variant
            L = np.linalg.norm(A2 - B, axis=1)
            cables = tuple(replace(c, ceiling_anchor=a, length=float(l)) for c, a, l in zip(rig.cables, A2, L))
            out.append((f"ceiling anchors {shift:g} m {word} along world {name}", replace(rig, cables=cables)))
    return out


def _rotational(modes) -> list[float]:
    """Frequencies (Hz) of the modes that are mostly rotation (> 30 % of their energy)."""
    return [m.frequency for m in modes if m.energy[3:].sum() > 0.3]


def _run_key(c: Candidate) -> tuple:
    """What makes a run distinct for the simulation caches: geometry, frequency, mounting
    point, spin axis and sense (the amplitude is fitted)."""
    return (c.geometry, c.run.frequency, c.run.position, c.run.spin_axis, c.run.direction)


def _best_pairs(cands: list[Candidate], n: int, ref: np.ndarray) -> list[tuple[Candidate, Candidate]]:
    """The ``n`` best distinct pairs of screened runs for a joint fit (information and noise
    of the two runs add; each with its own weights)."""
    B = np.array([np.einsum("a,aij->ij", c.prediction.weights, c.prediction.axis_bread) for c in cands])
    M = np.array([sum(np.einsum("a,b,abij->ij", c.prediction.weights, c.prediction.weights, m)
                      for m in c.prediction.axis_meats.values()) for c in cands])
    i, j = np.triu_indices(len(cands), 1)
    out = np.full(len(i), np.inf)
    for lo in range(0, len(i), 50000):
        sl = slice(lo, lo + 50000)
        Bs = B[i[sl]] + B[j[sl]]
        ok = np.linalg.cond(Bs) < 1e12
        Bi = np.zeros_like(Bs)
        Bi[ok] = np.linalg.inv(Bs[ok])
        var = np.einsum("pkl,plm,pkm->pk", Bi, M[i[sl]] + M[j[sl]], Bi)
        obj = np.max(np.sqrt(np.clip(var, 0, None)) / ref, axis=1)
        out[sl] = np.where(ok, obj, np.inf)
    order = np.argsort(out)
    taken: list[tuple[Candidate, Candidate]] = []
    for k in order:
        if not np.isfinite(out[k]):
            break
        a, b = cands[i[k]], cands[j[k]]
        if all(not (_same(a, x) and _same(b, y)) and not (_same(a, y) and _same(b, x)) for x, y in taken):
            taken.append((a, b))
        if len(taken) >= n:
            break
    return taken


def _same(a: Candidate, b: Candidate) -> bool:
    return (a.run.spin_axis == b.run.spin_axis and a.run.direction == b.run.direction
            and np.allclose(a.run.position, b.run.position) and abs(a.run.frequency / b.run.frequency - 1) < 0.15)


def resonances(mode_f) -> np.ndarray:
    """Frequencies (Hz) an exciter must stay away from: the natural frequencies f_i (primary
    resonance), 2 f_i and f_i + f_j (parametric and combination resonances: the rotating
    force modulates the cables' geometric stiffness; on the thesis rig 2.02 Hz = 0.85 + 1.18 Hz
    makes the swing grow until a cable goes slack, even at 160 N)."""
    f = np.asarray(mode_f, float)
    i, j = np.triu_indices(len(f))
    return np.unique(np.concatenate([f, f[i] + f[j]]))


def _distinct(cands: list[Candidate], n: int) -> list[Candidate]:
    """The first ``n`` candidates that differ in mounting point / spin axis or by ≥ 15 % in
    frequency from the ones already taken."""
    out: list[Candidate] = []
    for c in cands:
        if all(not _same(c, o) for o in out):
            out.append(c)
        if len(out) >= n:
            break
    return out


def load_plan_input(path) -> tuple[Rig, dict | None, np.ndarray | None]:
    """The rig of ``path`` — a rig.yaml, an experiment file (config/cases, config/rigs) or a
    recording folder — with its cable stiffness if known (rig.yaml ``stiffness`` or the
    experiment's spring ``cable_model``) and, for an experiment file, its rotating
    excitation ({amplitude, frequency, ramp_time}) as the baseline.  Raises
    :class:`~.rig.RigError`, :class:`~.recording.RecordingError`, FileNotFoundError."""
    from pathlib import Path

    from .recording import RecordingError
    from .rig import RigError, load_rig, read_yaml
    p = Path(path)
    if p.is_dir():
        if not (p / "rig.yaml").exists():
            raise RecordingError(f"{p}: no rig.yaml in the recording folder")
        p = p / "rig.yaml"
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    d = read_yaml(p, RigError, "rig description")
    if isinstance(d, dict) and "rig" in d and "gravity" not in d:
        from .simulator import ExperimentError, load_experiment
        try:
            exp = load_experiment(p)
        except ExperimentError as e:
            raise RigError(str(e)) from None
        k = exp.cable_model.stiffness if exp.cable_model.type == "spring" else None
        rot = exp.excitation.rotating
        base = None if rot is None else {"amplitude": rot.amplitude, "frequency": rot.frequency,
                                         "ramp_time": rot.ramp_time}
        return exp.rig, base, None if k is None else np.asarray(k, float)
    rig = load_rig(p)
    k = rig.cable_stiffness
    return rig, None, (k if np.all(np.isfinite(k)) else None)


def make_body(rig: Rig, mass: float | None, inertia_entries, stiffness=None, noise: dict | None = None,
              rates: dict | None = None) -> Body:
    """A :class:`Body` from the command line's numbers: mass kg (default rig.yaml's),
    inertia_entries (6,) in :data:`KEYS` order, kg·m² (tensor entries: products negated).
    Raises :class:`PlanError` for a non-positive mass, a missing CG or a tensor that is not
    physically consistent."""
    if rig.center_of_gravity is None:
        raise PlanError(f"{rig.source}: body.center_of_gravity is required (estimate it first: rig-identify cg)")
    m = float(rig.mass if mass is None else mass)
    if not (math.isfinite(m) and m > 0):
        raise PlanError(f"--mass must be > 0 kg, got {mass}")
    J = to_tensor(np.asarray(inertia_entries, float))
    if not np.all(np.isfinite(J)) or not physically_consistent(J):
        raise PlanError("--inertia: the tensor is not physically consistent (it must be positive definite and "
                        "each principal moment at most the sum of the other two); order IXX IYY IZZ IXY IXZ IYZ, "
                        "kg·m², products negated as in truth.yaml")
    n = len(rig.cables)
    k = np.full(n, DEFAULT_STIFFNESS) if stiffness is None else np.broadcast_to(np.asarray(stiffness, float), (n,))
    return Body(replace(rig, mass=m), m, J, np.array(k, float), dict(rates or REFERENCE_RATES),
                dict(noise or REFERENCE_NOISE))
