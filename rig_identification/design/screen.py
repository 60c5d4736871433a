"""The experiment design's fast screen: what a candidate run tells the rig model, from the rig
linearised about its rest pose — how :func:`~rig_identification.design.planning.plan_experiment`
ranks its many candidate runs before it simulates the best few.

The rig model's linearisation (:func:`~rig_identification.model.linear_rig.linearise`:
``M q'' + D q' + K q = B u`` about the rest pose, q = (δp of the body origin, world m; δφ, world
rad)) is driven from rest by a spinning-up rotating force, sampled at :data:`SCREEN_RATE` Hz
(the force held over each step at its mid-point value).  Every channel the rig model fits is an
output, linearised as the exact model reads it (:func:`~rig_identification.model.rig_ode.simulate`):

* each load cell: −g_i k_i (G_i q + τ G_i q') (its static reading is a constant the fit's
  residual does not see);
* the gyro, IMU axes: R_imuᵀ R0ᵀ δφ';
* the accelerometer, IMU axes: R_imuᵀ [R0ᵀ (a_cg + g e_z × δφ) + (R0ᵀ δφ'') × r], a_cg = δp'' +
  δφ'' × R0 c, r the IMU's offset from the CG;
* the inclinometer: (w_j × e_z)·δφ / √(1 − (e_z·w_j)²), w_j = R0 R_inc e_j.

The Fisher information of the body's unknowns (tensor, CG, mass) is that of every channel's
white noise at its rate (Ljung, *System Identification*, eq. 9.29 for Gaussian output error),
the sensitivities by central differences of the linearised rig over the rig model's unknowns
(:data:`SCREEN_UNKNOWNS`: tensor, CG, mass, each cable's log-stiffness, the cables' damping time,
each load cell's gain, the body's viscous damping), with the rig model's nuisance model: every
15 s segment's initial state free (projected out), the stiffness's and gains' priors
(:func:`~rig_identification.estimation.rig_unknowns.priors`).  Left out against the rig
model's bound (:mod:`~rig_identification.design.information`): the survey's σ on the geometry
and the exciter force's correction, and the fit's low-pass band acts only on the force (the
spin-up's content above 4× the exciter frequency removed).  A run is linear in its force: the
responses to the six body-frame wrench components (cos and sin of the rotating force) are
computed once per frequency and every mounting point, spin axis and sense combines them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm
from scipy.signal import butter, lfilter, sosfiltfilt
from scipy.spatial.transform import Rotation

from ..estimation.rig_record import FORCE_BAND, channel_names
from ..estimation.rig_unknowns import SEGMENT, Layout, Prior, parameters_of, priors, unit_scale, vector
from ..model.linear_rig import RestPose, RigParameters, linearise, rest_pose
from ..model.rigid_body import skew
from .information import BODY, RunInformation, channel_noise, nominal_parameters
from .run import Body

#: Hz, the screen's sampling rate (the rig model's band reaches 4× the exciter frequency: 16 Hz at 4 Hz).
SCREEN_RATE = 50.0


def screen_unknowns(lay: Layout) -> np.ndarray:
    """The indices into ``lay``'s vector of the unknowns the screen differentiates: the body's
    ten (:data:`~rig_identification.design.information.BODY`), then each cable's log-stiffness,
    the damping time, each load cell's gain and the body's viscous damping (2)."""
    return np.concatenate([np.arange(BODY), np.arange(lay.log_stiffness.start, lay.body_damping.stop)])


@dataclass(frozen=True)
class _Linear:
    """One parameter set's discrete linear rig: modal form of x_{k+1} = Ad x_k + Bd w_k (x = (q, q'),
    w the body-frame wrench (6,)), and the outputs y = C x + Cd x' = (C + Cd A) x + Cd Bc w."""

    lam: np.ndarray      # (12,) complex eigenvalues of Ad
    V: np.ndarray        # (12, 12) eigenvectors
    W: np.ndarray        # (12, 6) V⁻¹ Bd
    CV: np.ndarray       # (n_out, 12) (C + Cd A) V: the outputs of each mode
    D: np.ndarray        # (n_out, 6) Cd Bc: the outputs' direct share of the wrench


def _discrete(p: RigParameters, rest: RestPose, rate: float) -> _Linear:
    """The linear rig of ``p`` about ``rest`` (module docstring), discretised at ``rate`` Hz."""
    lin = linearise(p, rest)
    R0 = rest.rotation
    Mi = np.linalg.inv(lin.M)
    A = np.zeros((12, 12))
    A[:6, 6:] = np.eye(6)
    A[6:, :6] = -Mi @ lin.K
    A[6:, 6:] = -Mi @ lin.D
    Bc = np.zeros((12, 6))
    Bc[6:] = Mi @ np.block([[R0, np.zeros((3, 3))], [np.zeros((3, 3)), R0]])
    Z = np.zeros((18, 18))
    Z[:12, :12], Z[:12, 12:] = A, Bc
    E = expm(Z / rate)
    lam, V = np.linalg.eig(E[:12, :12])
    n = p.cables
    R_inc = p.inclinometer_rotation
    has_inc = R_inc is not None
    C = np.zeros((n + 6 + 2 * has_inc, 12))
    Cd = np.zeros_like(C)
    C[:n, :6] = -(p.gain * p.stiffness)[:, None] * lin.G
    C[:n, 6:] = p.damping_time * C[:n, :6]
    Ri = p.imu_rotation.T
    C[n:n + 3, 9:] = Ri @ R0.T
    c = R0 @ p.cg
    r = p.imu_position - p.cg
    ez = np.array([0.0, 0.0, 1.0])
    Cd[n + 3:n + 6, 6:9] = Ri @ R0.T
    Cd[n + 3:n + 6, 9:] = Ri @ (-R0.T @ skew(c) - skew(r) @ R0.T)
    C[n + 3:n + 6, 3:6] = Ri @ R0.T @ skew(p.gravity * ez)
    if R_inc is not None:
        for j in range(2):
            w = R0 @ R_inc[:, j]
            C[n + 6 + j, 3:6] = np.cross(w, ez) / np.sqrt(max(1.0 - w[2] ** 2, 1e-12))
    return _Linear(lam, V, np.linalg.solve(V, E[:12, 12:]), (C + Cd @ A) @ V, Cd @ Bc)


def _spin_up(f: float, t: np.ndarray, ramp: float) -> np.ndarray:
    """(n, 2) cos θ and sin θ times the amplitude factor of a unit rotating force with a spin-up
    ramp (as :class:`~rig_identification.model.simulator.RotatingForce`, ramp_shape spin_up)."""
    if ramp > 0:
        amp = np.where(t < ramp, (t / ramp) ** 2, 1.0)
        th = np.where(t < ramp, np.pi * f * t ** 2 / ramp, 2 * np.pi * f * (t - ramp / 2))
    else:
        amp, th = np.ones_like(t), 2 * np.pi * f * t
    return np.stack([amp * np.cos(th), amp * np.sin(th)], axis=1)


def _modal(s: _Linear, held: np.ndarray) -> np.ndarray:
    """(n, 12 modes, 2 signals, 6 components) the modal coordinates of the linear rig ``s`` from rest,
    driven by each signal of ``held`` (n, 2: its value over each step, the zero-order hold) times each
    body-frame wrench component."""
    z = np.stack([np.stack([lfilter([0.0, 1.0], [1.0, -lam], held[:, j].astype(complex)) for j in range(2)], axis=1)
                  for lam in s.lam], axis=1)                                   # (n, 12, 2)
    out: np.ndarray = z[:, :, :, None] * s.W[None, :, None, :]
    return out


def _states(s: _Linear, held: np.ndarray) -> np.ndarray:
    """(n, 12, 2, 6) the state's response (:func:`_modal`'s drive)."""
    Z = _modal(s, held)
    return np.asarray(np.matmul(s.V, Z.reshape(len(Z), 12, 12)).real.reshape(len(Z), 12, 2, 6))


def _readings(s: _Linear, held: np.ndarray, now: np.ndarray) -> np.ndarray:
    """(n, n_out, 2, 6) the outputs' response (:func:`_modal`'s drive); the accelerometer's direct
    share of the force takes ``now`` (n, 2: the signals at the samples)."""
    Z = _modal(s, held)
    Y = np.matmul(s.CV, Z.reshape(len(Z), 12, 12)).real.reshape(len(Z), -1, 2, 6)
    out: np.ndarray = Y + now[:, None, :, None] * s.D[None, :, None, :]
    return out


def _free(s: _Linear, n: int) -> np.ndarray:
    """(n, n_out, 12) the outputs of the free linear rig ``s`` over n samples from each unit initial state."""
    powers = s.lam[None, :] ** np.arange(n)[:, None]                          # (n, 12)
    out: np.ndarray = np.einsum("ci,ti,ij->tcj", s.CV, powers, np.linalg.inv(s.V), optimize=True).real
    return out


@dataclass(frozen=True)
class ScreenedRun:
    """A candidate run on the screen: its force amplitude N (within the limits, or given), the
    limit that binds it (``force``, ``rotation``, ``tension`` or ``given``), its peak rotation deg
    and lowest tension over static (start-up included), and what it tells the rig model."""

    amplitude: float
    limit: str
    rotation_deg: float
    min_tension_ratio: float
    information: RunInformation


class FrequencyScreen:
    """The screen at one exciter frequency: the state's response per newton of each wrench
    component (for the limits) and the Gram matrix of the body's and the nuisance's sensitivities
    per pair of wrench components (for the information).  Made by :meth:`RigScreen.at`."""

    def __init__(self, screen: "RigScreen", X: np.ndarray, Y: np.ndarray, gram: np.ndarray):
        self.screen, self.X, self.Y, self.gram = screen, X, Y, gram

    @staticmethod
    def wrench(position, rpy, direction: int = 1) -> np.ndarray:
        """(6, 2) the body-frame wrench about the body origin (force N, moment N·m) per newton of the
        rotating force's cos and sin, the exciter at ``position`` (3,) body m, its frame at ``rpy``
        (extrinsic xyz, rad, body -> exciter; the force turns in the frame's x-y plane, sense ``direction``)."""
        e = Rotation.from_euler("xyz", rpy).as_matrix()[:, :2] * np.array([1.0, float(direction)])   # (3, 2)
        return np.vstack([e, np.cross(np.asarray(position, float), e.T).T])

    def readings(self, position, rpy, amplitude: float, direction: int = 1) -> np.ndarray:
        """(n, n_out) the change of every reading the rig model fits (each load cell N, the gyro rad/s
        and the accelerometer m/s² in IMU axes, the inclinometer's two angles rad) from rest, at the
        screen's samples (``screen.t``), for the run of :meth:`candidate`'s arguments at ``amplitude`` N."""
        out: np.ndarray = amplitude * np.einsum("tcsj,js->tc", self.Y, self.wrench(position, rpy, direction))
        return out

    def candidate(self, position, rpy, limits: dict, amplitude: float | None = None,
                  direction: int = 1) -> ScreenedRun:
        """The run with the exciter at ``position`` (3,) body m, its frame at ``rpy`` (extrinsic xyz,
        rad, body -> exciter; the force turns in the frame's x-y plane, sense ``direction``), at the
        largest amplitude within ``limits`` (``max_force_n``, ``max_rotation_deg``,
        ``min_tension_ratio``: the linear rig's peak rotation and tension drop, 5 % margin) or at
        ``amplitude`` N."""
        sc = self.screen
        L = self.wrench(position, rpy, direction)
        x = np.einsum("tasj,js->ta", self.X, L)
        rot_unit = float(np.max(np.linalg.norm(x[:, 3:6], axis=1)))
        # a cable's tension falls by k G q + τ k G q' (δT = -k G q - τ k G q')
        drop = ((x[:, :6] @ sc.G.T) * sc.stiffness + (x[:, 6:] @ sc.G.T) * sc.damping) / sc.T0
        drop_unit = float(np.max(drop))
        lim = {"force": limits["max_force_n"],
               "rotation": np.radians(limits["max_rotation_deg"]) / max(rot_unit, 1e-300),
               "tension": (1 - limits["min_tension_ratio"]) / max(drop_unit, 1e-300)}
        key = min(lim, key=lambda k: lim[k])
        amp = 0.95 * lim[key] if key != "force" else lim[key]
        if amplitude is not None:
            amp, key = float(amplitude), "given"
        c = L.T.reshape(-1)                                          # (2·6,) in (signal, component) order
        info = amp ** 2 * np.einsum("i,iajb,j->ab", c, self.gram, c)
        return ScreenedRun(float(amp), key, float(np.degrees(rot_unit * amp)), 1 - drop_unit * amp,
                           sc.profiled(info))


class RigScreen:
    """The fast design screen of ``body``'s rig (module docstring) for runs of ``duration`` s, the
    fit from ``settle`` s, the force spun up over ``ramp`` s.  Raises
    :class:`~rig_identification.model.rigid_body.SimulationError` where the rig has no taut rest pose."""

    def __init__(self, body: Body, duration: float, settle: float, ramp: float = 2.0, rate: float = SCREEN_RATE):
        self.duration, self.settle, self.ramp, self.rate = duration, settle, ramp, rate
        rig = body.rig
        p = nominal_parameters(rig, body.inertia, body.stiffness, body.mass)
        n = len(rig.cables)
        lay = Layout(n)
        x0 = vector(p, np.zeros(12), lay)
        prior = Prior.from_rig(rig)
        self.idx = screen_unknowns(lay)
        self.step = unit_scale(x0, lay, prior)[self.idx]
        _, std = priors(prior, lay, x0)
        self.prior_info = np.where(np.isfinite(std[self.idx]), (self.step / std[self.idx]) ** 2, 0.0)   # in steps
        self.prior_info[:BODY] = 0.0          # the body's priors count once over the runs (information.combined)
        self.rest = rest_pose(p)
        self.nominal = _discrete(p, self.rest, rate)
        self.sets = []
        for i, h in zip(self.idx, self.step):
            pair = []
            for sign in (1.0, -1.0):
                x = x0.copy()
                x[i] += sign * h
                q = parameters_of(x, p, lay)
                pair.append(_discrete(q, rest_pose(q, near=self.rest), rate))
            self.sets.append(pair)
        lin = linearise(p, self.rest)
        self.G, self.T0 = lin.G, self.rest.tensions
        self.stiffness, self.damping = p.stiffness, p.damping_time * p.stiffness
        self.t = np.arange(int(round(duration * rate)) + 1) / rate
        self.first = int(np.searchsorted(self.t, settle))
        has_inc = rig.inclinometer is not None
        sig = channel_noise(channel_names(rig), body.noise)
        rates = np.concatenate([np.full(n, body.rates["load_cells"]), np.full(6, body.rates["imu"]),
                                np.full(2 * has_inc, body.rates.get("inclinometer", 0.0))])
        self.weight = np.sqrt(rates / rate) / sig
        seg = int(round(SEGMENT * rate))
        self.segments = [(a, min(a + seg, len(self.t))) for a in range(self.first, len(self.t) - 1, seg)]
        free = _free(self.nominal, seg) * self.weight[None, :, None]
        self.free_q = [np.linalg.qr(free[:b - a].reshape(-1, 12))[0] for a, b in self.segments]

    def at(self, f: float) -> FrequencyScreen:
        """The screen at the exciter frequency ``f`` Hz."""
        held, now = _spin_up(f, self.t + 0.5 / self.rate, self.ramp), _spin_up(f, self.t, self.ramp)
        X, Y = _states(self.nominal, held), _readings(self.nominal, held, now)
        sos = butter(4, min(FORCE_BAND * f, 0.45 * self.rate), fs=self.rate, output="sos")
        held, now = sosfiltfilt(sos, held, axis=0), sosfiltfilt(sos, now, axis=0)
        n_out, P = len(self.weight), len(self.idx)
        S = np.empty((len(self.t), n_out, 2, 6, P))
        for a, (plus, minus) in enumerate(self.sets):
            S[..., a] = (_readings(plus, held, now) - _readings(minus, held, now)) / 2   # per step
        S *= self.weight[None, :, None, None, None]
        gram = np.zeros((2, 6, P, 2, 6, P))
        for (a, b), Q in zip(self.segments, self.free_q):
            s = S[a:b].reshape(-1, 12 * P)
            s = s - Q @ (Q.T @ s)
            gram += (s.T @ s).reshape(2, 6, P, 2, 6, P)
        return FrequencyScreen(self, X, Y, gram.reshape(12, P, 12, P))

    def profiled(self, info: np.ndarray) -> RunInformation:
        """The :class:`RunInformation` of a run whose information over the screen's unknowns (in
        their steps' units) is ``info`` (P, P): the nuisance's priors added, the nuisance profiled
        out (the Schur complement), in the body's units (tensor kg·m², CG m, mass kg)."""
        full = info + np.diag(self.prior_info)
        bb, bn, nn = full[:BODY, :BODY], full[:BODY, BODY:], full[BODY:, BODY:]
        body = bb - bn @ np.linalg.solve(nn, bn.T)
        h = self.step[:BODY]
        return RunInformation(body / np.outer(h, h), self.duration - self.settle)


__all__ = ["SCREEN_RATE", "FrequencyScreen", "RigScreen", "ScreenedRun", "screen_unknowns"]
