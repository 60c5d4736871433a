"""Noise propagation: the σ of the identified tensor that the sensors' noise causes along a run.

The identifier (:mod:`rig_identification.estimation.identification`) fits ``J`` by weighted least squares on the
band-passed gyro ``y = F ω`` against ``ŷ = J⁻¹ F ∫(M − ω × Jω)``.  To first order in the
sensor noise its error is ``δj = (AᵀWA)⁻¹ AᵀW e`` (A: the (N·3, 6) Jacobian of ŷ at the
nominal tensor, W: the per-axis weights 1/σ² of its Levenberg–Marquardt stage, e: the
residual the noise causes).  The noise reaches e by three paths:

* the gyro itself (the output): ``F n_g`` — the identifier's own white-noise bound
  ``crb_std`` covers only this path;
* the tracker: its pose is the integrated gyro (and accelerometer) noise, held to the
  inclinometer / cable constraints by slow complementary filters.  A pose error φ turns
  the measured cable tensions into a torque error ``δM = D_φ(t) φ + D_p(t) δp`` (the
  moment of the weight about the CG "seen" at the wrong angle: D_φ ~ m g h ~ 7·10⁴ N·m/rad
  on the thesis rig), which the identifier integrates: ``e = −J⁻¹ F ∫ δM``.  Because
  ``∫∫`` makes this path ∝ (f_pendulum / f)², it is as large as the direct gyro path
  near the rig's modes and dominates the pitch axis of thesis case 16;
* the load cells and the exciter's load cells: white torque errors, also integrated.

:func:`predict_from_trajectory` evaluates that linear map exactly for the run's true
motion (a noise-free simulation, cut to the span the identifier would fit): the tracker is
linearised about the equilibrium (its complementary filters — tilt, yaw, gyro-bias integral,
third-order position filter — as transfer functions, parameters read from
:class:`~rig_identification.estimation.tracker.PoseTracker`), ``D_φ(t)``, ``D_p(t)`` and the load cells' lever arms are
the derivatives of :func:`~rig_identification.estimation.preprocessor.generalized_wrench` at every sample (so a slow
pose error modulated by the tension swing lands at the exciter frequency), and the
identifier's own band-pass (``sosfiltfilt``, edge transients included) and integration are
applied through their transposes, so that ``Cov δj = B⁻¹ (Σ_c σ_c² Γ_cᵀΓ_c) B⁻¹`` (B = AᵀWA,
Γ_c the sensitivity of ``AᵀW e`` to noise channel c) needs no Monte Carlo.  The tracker's
online cable compliance (rig.yaml without stiffness) enters as one more linear functional
of the noise (its estimate lengthens every constraint by T(t)·δc).  Realisation by
realisation this linear model reproduces the pipeline's residual (correlation 0.995) and
estimate errors (0.99+); on thesis cases 10–17 its σ match the spread of 60 Monte Carlo
replays per case within ±20 % on 46 of 48 entries (median ratio 1.00; the pitch inertia Iyy is
predicted 10–25 % conservative on some cases), where the white-gyro bound alone is off by
−23 … +130 % (``bench/bench_plan.py``).  Second-order effects (errors in the integrated torque acting as
errors in variables: a bias of least squares) are not modelled here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft
from scipy.signal import butter, sosfreqz
from scipy.spatial.transform import Rotation

from ..io.recording import Recording, RecordingError
from ..io.rig import Rig
from ..model.dynamics import skew, skews
from ..model.experiment import REFERENCE_NOISE
from ..model.parametrisation import basis, from_tensor
from .adjoints import cumtrapz_adjoint, sosfiltfilt_adjoint
from .gyro_fit import prepare_segment
from .linearisation import TrackerModel, tracker_model, wrench_jacobians
from .prediction import PlanError, Prediction
from .preprocessor import generalized_wrench
from .quality import clean_sensors
from .signals import auto_band

if TYPE_CHECKING:
    from ..model.simulator import SimResult

FREQ_BLOCK = 4096   # frequencies per evaluation of the tracker's response (memory, not results)

SOURCES = ("gyro", "accelerometer", "inclinometer", "load_cell", "exciter")
"""Noise sources of the prediction (the tracker's compliance estimate enters through them)."""


@dataclass
class Trajectory:
    """The true motion of a planned run at the IMU samples (noise-free simulation).

    t (K,) s from the start; omega (K,3) rad/s body; torque (K,3) N·m about the CG, body;
    position (K,3) world m of the body origin; R (K,3,3) body -> world; tensions (K,N) N;
    exciter_xy (K,2) N or None; rig; inertia (3,3) nominal tensor; rates (Hz per stream)."""

    t: np.ndarray
    omega: np.ndarray
    torque: np.ndarray
    position: np.ndarray
    R: np.ndarray
    tensions: np.ndarray
    exciter_xy: np.ndarray | None
    rig: Rig
    inertia: np.ndarray
    rates: dict[str, float]

    warnings: list[str] = field(default_factory=list)

    @staticmethod
    def from_simulation(sim: SimResult, clean: bool = True) -> "Trajectory":
        """From a noise-free :class:`~rig_identification.model.simulator.SimResult` (its States at the IMU samples).
        clean: keep only the span the identifier would fit — the longest one free of slack
        cables, saturation and gaps (:func:`~rig_identification.estimation.quality.clean_sensors`) — with its warnings.
        Raises :class:`PlanError` if less than the identifier's minimum is clean."""
        st = sim.states
        keep = np.ones(len(st.t), bool)
        warnings: list[str] = []
        if clean:
            try:
                s = clean_sensors(Recording(sim.rig, sim.sensors, sim.truth,
                                            "planned run"), warnings)  # type: ignore[arg-type]  # path: a label, not a Path
            except RecordingError as e:
                raise PlanError(str(e)) from None
            keep = (st.t >= s.t_start - 1e-9) & (st.t <= s.t_end + 1e-9)
        t = st.t[keep] - sim.experiment.stamp_origin
        rig = sim.rig
        R = st.rotation.as_matrix()[keep]
        exc = None
        if sim.sensors.exciter is not None and rig.exciter is not None:
            exc = sim.sensors.exciter.interp(st.t[keep])
        _, torque = generalized_wrench(rig, st.position[keep], R, st.tensions[keep], exc)
        return Trajectory(t, st.omega[keep].copy(), torque, st.position[keep].copy(), R, st.tensions[keep].copy(), exc,
                          rig, sim.experiment.inertia, dict(sim.experiment.sensors.rates), warnings)


def _weights_stationary(tm: TrackerModel, rig: Rig, D: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                        P: np.ndarray, sos: np.ndarray, fs: float,
                        sig: np.ndarray, n: int) -> np.ndarray:
    """Per-axis variance (3,) of the residual e predicted by the stationary form of the
    noise model (time-averaged sensitivities): the identifier's LM weights are 1/σ²."""
    f = np.fft.rfftfreq(n, 1 / fs)
    mult = np.full(len(f), 2.0)
    mult[0] = 1.0
    if n % 2 == 0:
        mult[-1] = 1.0
    R_imu = rig.imu.rotation.as_matrix()
    var = np.zeros(3)
    for lo in range(0, len(f), FREQ_BLOCK):   # a block of frequencies at a time (memory)
        Hf = stationary_e_response(tm, D, P, sos, fs, f[lo:lo + FREQ_BLOCK], R_imu)
        var += np.einsum("k,kad,d,kad->a", mult[lo:lo + FREQ_BLOCK], Hf, sig**2, Hf.conj()).real
    return var / n


def stationary_e_response(tm: TrackerModel, D: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], P: np.ndarray,
                          sos: np.ndarray, fs: float, f: np.ndarray, R_imu: np.ndarray) -> np.ndarray:
    """(K,3,d) response of the residual e to the noise channels, time-averaged sensitivities."""
    D_phi, D_p, W_T, W_e = (np.mean(x, axis=0) for x in D)
    Ht = tm.response(f)[:, :, :8]
    _, hf = sosfreqz(sos, worN=f, fs=fs)
    F = np.abs(hf) ** 2
    n_T = W_T.shape[1]
    d = 8 + n_T + 2
    H = np.zeros((len(f), 3, d), complex)
    nz = f > 0
    s = 2j * np.pi * f[nz]
    dM = np.zeros((nz.sum(), 3, d), complex)
    dM[:, :, :8] = np.einsum("ij,kjd->kid", D_phi, Ht[nz, :3]) + np.einsum("ij,kjd->kid", D_p, Ht[nz, 3:])
    dM[:, :, 8:8 + n_T] = W_T
    dM[:, :, 8 + n_T:] = W_e
    H[nz] = -np.einsum("ij,kjd->kid", P, dM) / s[:, None, None]
    H[nz, :, :3] += R_imu
    He: np.ndarray = H * F[:, None, None]
    return He


def channel_sigmas(noise: dict[str, float], rates: dict[str, float], fs: float, n_cables: int,
                   has_incl: bool) -> tuple[np.ndarray, list[str]]:
    """Per-IMU-sample equivalent σ of every noise channel and its source name.  A stream
    at rate r < fs has the in-band density of white noise σ·sqrt(fs/r) at fs."""
    def eq(key: str, rate_key: str) -> float:
        return noise[key] * math.sqrt(fs / rates[rate_key])
    sig = [noise["gyro"]] * 3 + [noise["accelerometer"]] * 3
    src = ["gyro"] * 3 + ["accelerometer"] * 3
    sig += [eq("inclinometer", "inclinometer") if has_incl else 0.0] * 2
    src += ["inclinometer"] * 2
    sig += [eq("load_cell", "load_cells")] * n_cables
    src += ["load_cell"] * n_cables
    sig += [eq("exciter", "exciter")] * 2
    src += ["exciter"] * 2
    return np.array(sig), src


def _adapts_compliance(rig: Rig, tracker_params: dict[str, Any] | None) -> bool:
    """Whether :class:`~rig_identification.estimation.tracker.PoseTracker` refines the cable compliance online (no
    stiffness in rig.yaml, an inclinometer and load cells)."""
    return rig.inclinometer is not None and not np.isfinite(rig.cable_stiffness).all()


def predict_from_trajectory(traj: Trajectory, noise: dict[str, float] | None = None, settle: float = 5.0,
                            band_hz: tuple[float, float] | None = None, tracker_params: dict[str, Any] | None = None,
                            seed: int = 0, gyro_sensitivity: bool = False) -> Prediction:
    """Predicted σ of the identified tensor for the run ``traj`` (see module docstring).

    noise: σ per source (keys of :data:`REFERENCE_NOISE`; default the reference levels),
    at ``traj.rates``.  settle: s skipped at the start, as
    :func:`~rig_identification.pipeline.offline.identify_recording`.  band_hz: the fit's pass band (default: what
    :func:`~rig_identification.estimation.signals.auto_band` picks on the gyro with this noise, seeded by
    ``seed``).  gyro_sensitivity: also return the per-sample linear map from the gyro
    noise to the estimate error (``Prediction.gyro_sensitivity``).  Raises
    :class:`PlanError` when the body hardly moves.
    """
    noise = dict(REFERENCE_NOISE if noise is None else noise)
    rig, t = traj.rig, traj.t
    fs = 1.0 / float(np.median(np.diff(t)))
    K = len(t)
    settle = min(settle, 0.1 * (t[-1] - t[0]))
    m = t >= t[0] + max(settle, 0.1) - 1e-9  # as identify_recording: settle time (after the tracker start)
    tw = t[m]
    J = np.asarray(traj.inertia, float)
    P = np.linalg.inv(J)
    duration = tw[-1] - tw[0]
    if band_hz is None:
        rng = np.random.default_rng(seed)
        w_noisy = traj.omega[m] + noise["gyro"] * rng.standard_normal((len(tw), 3))
        lo, hi = auto_band(w_noisy, fs)
        lo = max(lo, 2.0 / duration)
        band_hz = (lo, hi)
    try:
        seg = prepare_segment(tw, traj.omega[m], traj.torque[m], band_hz, what="planned run")
    except ValueError as e:
        raise PlanError(str(e)) from None
    lo, hi = seg.band
    sos = butter(4, [lo, hi], btype="bandpass", fs=fs, output="sos")  # the identifier's prefilter
    E = basis()
    j = from_tensor(J)
    u = seg.IM - np.einsum("m,mni->ni", j, seg.G)
    yhat = u @ P.T
    A3 = -np.einsum("ij,knj->nik", P, np.einsum("kij,nj->kni", E, yhat) + seg.G)   # (Nw,3,6)
    # the tracker and preprocessor sensitivities
    R0 = Rotation.from_matrix(traj.R).mean().as_matrix()
    tm = tracker_model(rig, traj.position.mean(0), R0, tracker_params)
    D = wrench_jacobians(rig, traj.position, traj.R, traj.tensions, traj.exciter_xy)
    sig, src = channel_sigmas(noise, traj.rates, fs, traj.tensions.shape[1], rig.inclinometer is not None)
    resid_var = _weights_stationary(tm, rig, D, P, sos, fs, sig, len(tw))
    # adjoint, one gyro axis at a time: Γ_a,k = d(Σ_t A_t,aᵀ e_t,a)/d noise (unweighted);
    # the weighted estimator's Γ = Σ_a w_a Γ_a.  Column (a, k) sees the residual of axis a
    # only: the adjoints of the band-pass and of the integral (linear, column by column) act
    # once on A3's 18 columns, and the moment's path (e = −P z) scales them by P[a, ·]
    Nw = len(tw)
    i0 = K - Nw                                                  # the window: the trajectory's tail
    H1 = sosfiltfilt_adjoint(sos, A3.reshape(Nw, 18))            # d/d(gyro noise, body), direct path
    h = cumtrapz_adjoint(H1, 1.0 / fs).T.reshape(3, 6, Nw)       # (a, k, n) d/d z per unit P
    H1 = H1.T.reshape(3, 6, Nw)
    R_imu = rig.imu.rotation.as_matrix()
    D_phi, D_p, W_T, W_e = (x[i0:] for x in D)

    def through_moment(Dm: np.ndarray) -> np.ndarray:
        """Γ (c, a, k, Nw) of the c noise channels whose moment error (body axes) is Dm (Nw,3,c)
        times the channel: −(P Dm)[a, c] h[a, k]."""
        G: np.ndarray = -np.einsum("ab,nbc->can", P, Dm)[:, :, None, :] * h[None]
        return G

    # gyroscopic term: δM -= ω × J n + n × J ω (n: body-axis gyro noise)
    Om = traj.omega[i0:]
    Sk = skews(Om)
    SJ = skews(Om @ J.T)
    n_T = W_T.shape[2]
    # Γ's products per channel d, Σ_n Γ[d,a,k,n] Γ[d,b,l,n] (18,18): the load cells' and the
    # exciter's (zero before the window) now, the others once Γ (channels 0-7) is complete
    meat = [None] * (8 + n_T + 2)
    for d0, Dm in ((8, W_T), (8 + n_T, W_e)):
        for c, g in enumerate(through_moment(Dm).reshape(-1, 18, Nw)):
            meat[d0 + c] = g @ g.T
    # the pose errors' channels, −(P D)[a, c] (c: rotation 3, position 3), times h[a] per weight axis
    Q_pe = -np.einsum("ab,nbc->can", P, np.concatenate([D_phi, D_p], axis=2))   # (6, a, Nw)
    # the tracker is causal LTI from the start; its adjoint is the correlation with its response,
    # by FFT over ≥ 2K samples (a fast length: 2K may be twice a prime).  Its inputs in blocks of
    # four (memory: one block's response and Γ at a time): the cable lengths' first — they give
    # the compliance's estimating equation (when the tracker adapts it) — then channels 0-7
    adapts = _adapts_compliance(rig, tracker_params)
    nfft = next_fast_len(2 * K, real=True)
    f = np.fft.rfftfreq(nfft, 1 / fs)
    blocks = ([(8, 8 + n_T)] if adapts else []) + [(0, 4), (4, 8)]
    gsens = np.zeros((3, 6))                                      # the estimating equation per unit δc
    gam_spec = None
    if adapts:
        # the tracker's cable compliance (rig.yaml without stiffness): its estimate
        # δc = <e_len, ΔT>/<ΔT, ΔT> over the first pass's second half
        # (tracker_replay.pass_compliance) is a linear function γᵀn of the noise, and lengthens
        # every constraint by ΔT(t)·δc: the static part offsets the pose for the whole run (seen
        # through the tension swing in D(t)), the dynamic part pulls the pose at the exciter
        # frequency
        dT = traj.tensions - traj.tensions[t < t[0] + 0.1 + 1e-9].mean(0)
        late = t >= t[0] + 0.5 * (t[-1] - t[0])
        S1 = float(np.sum(dT[late] ** 2))
        if S1 > 0:
            e_phi = -(tm.V - tm.U @ skew(tm.r_imu_w))              # e_len = e_phi φ - U δp_o
            gam_pe = np.zeros((6, K))
            gam_pe[:3, late] = (dT[late] @ e_phi / S1).T
            gam_pe[3:, late] = (-dT[late] @ tm.U / S1).T
            gam_spec = rfft(gam_pe, n=nfft, axis=-1)                 # (6, F)
    x = np.zeros((6, 3, nfft))
    gyro_gam = None
    for r0, r1 in blocks:
        Hb = np.empty((len(f), r1 - r0, 6), complex)              # conjugated response (F, inputs, 6)
        for lo in range(0, len(f), FREQ_BLOCK):
            Hb[lo:lo + FREQ_BLOCK] = tm.response(f[lo:lo + FREQ_BLOCK])[:, :, r0:r1].conj().transpose(0, 2, 1)
        Gb = np.zeros((r1 - r0, 3, 6, K)) if r0 < 8 else None     # Γ (channel, a, k, n)
        if r0 == 0:   # body gyro noise = R_imu · IMU-axis noise: the direct path, the gyroscopic moment's
            Gb[:3, :, :, i0:] = (R_imu.T[:, :, None, None] * H1[None]  # type: ignore[index]  # r0 < 8: an array
                                 - through_moment((Sk @ J - SJ) @ R_imu))
        for a in range(3):   # a weight axis and three entries at a time
            for k in (slice(0, 3), slice(3, 6)):
                x[..., i0:K] = Q_pe[:, a, None, :] * h[a, k][None]
                S = rfft(x, axis=-1).transpose(2, 0, 1)           # (F, 6, 3)
                g_tr = irfft(np.matmul(Hb, S).transpose(1, 2, 0), n=nfft, axis=-1)[..., :K]   # (inputs, 3, K)
                if Gb is None:
                    gsens[a, k] = np.einsum("ni,ikn->k", traj.tensions, g_tr)
                else:
                    Gb[:, a, k] += g_tr
                del S, g_tr
        if Gb is not None:
            if gam_spec is not None:
                gam = irfft(np.einsum("fdo,of->df", Hb, gam_spec), n=nfft, axis=-1)[:, :K]
                Gb += gam[:, None, None, :] * gsens[None, :, :, None]
            for d, g in enumerate(Gb.reshape(r1 - r0, 18, K)):
                meat[r0 + d] = g @ g.T
            if r0 == 0 and gyro_sensitivity:
                gyro_gam = Gb[:3]
        del Hb, Gb
    del x
    axis_meats = {}
    for s_name in SOURCES:
        sel = np.nonzero((np.array(src) == s_name) & (sig > 0))[0]
        if len(sel):
            # Σ_nd σ_d² Γ[d,a,k,n] Γ[d,b,l,n]
            M = sum(sig[i] ** 2 * meat[i] for i in sel)
            axis_meats[s_name] = M.reshape(3, 6, 3, 6).transpose(0, 2, 1, 3)
    axis_bread = np.einsum("nai,naj->aij", A3, A3)
    A = A3.reshape(-1, 6)
    FA = seg.filt(A3.reshape(Nw, -1)).reshape(-1, 6)
    pred = Prediction.assemble(J, axis_bread, axis_meats, A.T @ A, noise["gyro"] ** 2 * FA.T @ FA, resid_var,
                               seg.band, float(duration), Nw, np.sqrt(np.mean(seg.y**2, axis=0)))
    if gyro_sensitivity:   # δj = B⁻¹ Σ_a w_a Γ_aᵀ ν, the same pieces as the sandwich
        Bi = np.linalg.inv(np.einsum("a,aij->ij", pred.weights, axis_bread))
        pred.gyro_sensitivity = np.einsum("kl,ndl->ndk", Bi,  # gyro_gam: set by the block r0 = 0
                                          np.einsum("a,dakn->ndk", pred.weights, gyro_gam))  # type: ignore[arg-type]
    return pred
