"""The experiment design's fast screen: the rig linearised about its static equilibrium
(:func:`linear_rig`), driven from rest by a spinning-up rotating force, with the stationary
form of the noise model (:class:`DesignScreen`) — how
:func:`~rig_identification.design.planning.plan_experiment` ranks its many candidate runs before
it simulates the best few.

Frames: the linear rig's coordinates are the CG's displacement (3, world, m) and a small
world rotation (3, rad); the screen's body rates are in body axes (rad/s).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm
from scipy.signal import butter, sosfreqz
from scipy.spatial.transform import Rotation

from ..estimation.linearisation import tracker_model, wrench_jacobians
from ..estimation.prediction import Prediction
from ..estimation.propagation import channel_sigmas, stationary_e_response
from ..model.cables import CableModel
from ..model.equilibrium import equilibrium
from ..model.modes import gradients, length_fn, length_hessians
from ..model.parametrisation import basis
from .run import Body, recommended_band


@dataclass(frozen=True)
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
    """Linearise the spring-cable rig about its equilibrium (as :func:`~rig_identification.model.modes.natural_modes`,
    plus the cables' damping), for the steady-state response of the design screen."""
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
    ramp (as :class:`~rig_identification.model.simulator.RotatingForce` with ramp_shape spin_up, direction +1)."""
    t = np.asarray(t, float)
    if ramp > 0:
        amp = np.where(t < ramp, (t / ramp) ** 2, 1.0)
        th = np.where(t < ramp, np.pi * f * t**2 / ramp, 2 * np.pi * f * (t - ramp / 2))
    else:
        amp, th = np.ones_like(t), 2 * np.pi * f * t
    return amp * np.cos(th), amp * np.sin(th)


class DesignScreen:
    """Fast design screen: the linearised rig (:func:`linear_rig`) driven by the rotating
    force from rest (spin-up, transients and steady state), sampled at ``fs_screen``, and
    the stationary form of the noise model (no filter edges, time-averaged sensitivities).

    body: :class:`~rig_identification.design.run.Body`; lin: its :func:`linear_rig`; duration, settle and
    ramp s: the run, the start of the fitted window, the spin-up; fs_screen Hz;
    tracker_params: the tracker's (:func:`~rig_identification.estimation.linearisation.tracker_model`).  Raises
    numpy.linalg.LinAlgError when the linearised mass matrix is singular (not for a body
    from :func:`~rig_identification.design.run.make_body`)."""

    def __init__(self, body: Body, lin: LinearRig, duration: float, settle: float, ramp: float = 2.0,
                 fs_screen: float = 50.0, tracker_params: dict | None = None):
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
