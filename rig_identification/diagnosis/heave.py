"""The compliant body's vertical channel: the sprung mass share and its heave mode.

Newton's law of the whole body along body z: the load cells' and the exciter's generalized
force over the mass against the frame's specific force at the CG (the accelerometer moved to
the CG with the gyro): a rigid body gives the same, a sprung mass m_s lagging on its springs
adds m_s δ̈ (Newton–Euler of the two bodies).  :func:`fit_heave` fits the share and the mode,
compensated for the accelerometer's noise in both sides; :class:`Heave` is its answer.  Used
by :func:`~rig_identification.diagnosis.compliant_body.fit_compliant_body` on the replays of
its window (``Window``: t, gyro, force, accel at the sensors' rate, body axes).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt
from scipy.stats import chi2

from ..estimation import two_body as tb
from ..estimation.errors_in_variables import EIV_LIMIT


@dataclass(frozen=True)
class Heave:
    """The vertical channel: the sprung mass share (σ) and its heave mode (frequency Hz,
    damping ratio), or ``determined`` False with ``why`` (no vertical motion, say).  An
    estimate, not a validated one: on bench_compliant_body's seed 9101 (the exciter spinning
    about x, heave at 2.99 Hz) it gave 0.62 ± 0.004 for a share of 0.73 (``python
    bench/bench_compliant_body.py --rigs 2``, the "share" column), so it does not enter the
    plausibility."""

    determined: bool
    mass_share: float | None = None
    mass_share_std: float | None = None
    frequency: float | None = None
    damping_ratio: float | None = None
    why: str = ""

    def to_dict(self) -> dict:
        return {"determined": self.determined, "mass_share": self.mass_share, "mass_share_std": self.mass_share_std,
                "frequency_hz": self.frequency, "damping_ratio": self.damping_ratio, "why": self.why}

HEAVE_FREQUENCIES = tuple(float(f) for f in np.round(np.geomspace(0.8, 4.0, 41), 4))
HEAVE_DAMPING = (0.03, 0.06, 0.1, 0.15, 0.2, 0.3, 0.45, 0.6)
HEAVE_SNR = 10.0            # the vertical regressor's RMS over its noise's below which heave is not determined
MASS_SHARE_STD_LIMIT = 0.1  # σ of the mass share beyond which it is not determined


def vertical(w, rig, cg: np.ndarray, sos: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """The vertical channel of one replay, band-passed: (Newton's residual F_z/m − f_c,z (N,),
    the frame's specific force at the CG f_c,z (N,)), m/s², body z.  f_c = f_imu − α × ρ −
    ω × (ω × ρ) (ρ = IMU − CG, α the gyro's derivative): the frame's; F the load cells' and
    the exciter's generalized force.  A rigid body gives F/m = f_c; a sprung mass m_s lagging
    on its springs adds m_s δ̈ (Newton–Euler of the two bodies)."""
    rho = rig.imu.position - cg
    alpha = np.gradient(w.gyro, w.t, axis=0)
    fc = w.accel - np.cross(alpha, rho) - np.cross(w.gyro, np.cross(w.gyro, rho))
    r = w.force[:, 2] / rig.mass - fc[:, 2]
    return sosfiltfilt(sos, r), sosfiltfilt(sos, fc[:, 2])


HEAVE_LR = float(chi2.ppf(0.95, 1))   # the mass share's profile-likelihood interval (95 %)


def fit_heave(base, pairs: list, rig, band: tuple, transient: float) -> Heave:
    """The heave mode and the sprung mass share s from the vertical channel (:func:`vertical`)
    of the window ``base`` and the antithetic ``pairs`` of its replays with fresh noise, over
    the samples after ``transient`` s (the modes start from rest):
    r = s G_h(s) f_c,z (G_h the base-excited oscillator of
    :func:`~rig_identification.estimation.two_body.oscillator`), linear in s for each (f, ζ) of
    the grid :data:`HEAVE_FREQUENCIES` × :data:`HEAVE_DAMPING`.  The accelerometer's noise is in
    both r and f_c,z (with opposite signs): bias-compensated least squares over the band's DFT
    bins, weighted by r's noise spectrum (the second moments of the replays' realisations
    removed from the normal equation and from the cost: Söderström 2018 ch. 5), the grid point
    of least corrected cost.  σ of s: half its profile interval (corrected cost within
    :data:`HEAVE_LR` of the least, in units of the weighted noise) — a heave mode above the
    band leaves only s / f² determined: not determined then (bench_compliant_body's seed
    9101, heave at 2.99 Hz above a 2.2 Hz band: 0.62 for 0.73), nor when the regressor hardly
    exceeds its noise (:data:`HEAVE_SNR`: an exciter spinning about the vertical hardly moves
    the body up and down; below it the compensation's first order fails), its noise share
    exceeds :data:`~rig_identification.estimation.errors_in_variables.EIV_LIMIT`, or σ(s) >
    :data:`MASS_SHARE_STD_LIMIT`."""
    cg = rig.require_cg()
    fs = 1.0 / float(np.median(np.diff(base.t)))
    sos = butter(4, list(band), btype="bandpass", fs=fs, output="sos")
    r, fc = vertical(base, rig, cg, sos, fs)
    reps = [(vertical(a, rig, cg, sos, fs), vertical(b, rig, cg, sos, fs)) for a, b in pairs]
    dr = np.array([0.5 * (a[0] - b[0]) for a, b in reps])
    dfc = np.array([0.5 * (a[1] - b[1]) for a, b in reps])
    keep = base.t >= base.t[0] + transient
    snr = float(np.sqrt(np.mean(fc[keep] ** 2)) / max(np.sqrt(np.mean(dfc[:, keep] ** 2)), 1e-300))
    if snr < HEAVE_SNR:
        return Heave(False, why=f"the body hardly moved vertically (the frame's vertical specific force in the band "
                                f"is {snr:.1f}× its noise): the exciter's force has no vertical component")
    n = int(keep.sum())
    fr = np.fft.rfftfreq(n, 1.0 / fs)
    bins = np.nonzero((fr >= band[0]) & (fr <= band[1]))[0]
    width = max(3, int(round(tb.SMOOTH_HZ * n / fs)) | 1)
    R, dR = np.fft.rfft(r[keep])[bins], np.fft.rfft(dr[:, keep], axis=1)[:, bins]
    W = 1.0 / np.maximum(np.convolve(np.mean(np.abs(dR) ** 2, axis=0), np.ones(width) / width, mode="same"), 1e-300)
    fits = []
    for f in HEAVE_FREQUENCIES:
        for z in HEAVE_DAMPING:
            g = tb.oscillator(np.concatenate([fc[None], dfc]), f, z, fs)[:, keep]
            G = np.fft.rfft(g, axis=1)[:, bins]
            a = float(np.sum(W * np.abs(G[0]) ** 2))
            b = float(np.sum(W * (G[0].conj() * R).real))
            # least squares picks the mode (the noise's second moments, subtracted, would reward the
            # grid points where they happen to be large); the share is then compensated
            cost = 2.0 * float(np.sum(W * np.abs(R) ** 2) - b * b / a)
            noise_gg = float(np.mean(np.sum(W * np.abs(G[1:]) ** 2, axis=1)))
            noise_gr = float(np.mean(np.sum(W * (G[1:].conj() * dR).real, axis=1)))
            fits.append((cost, f, z, a, b, noise_gg, noise_gr))
    c0, f0, z0, a, b, ngg, ngr = min(fits)
    share = ngg / a
    if not share <= EIV_LIMIT:
        return Heave(False, why=f"the noise is {100 * share:.0f} % of the vertical regressor at the heave mode "
                                f"({f0:.2f} Hz): the mass share is not determined")
    s0 = (b - ngr) / (a - ngg)
    if not band[0] <= f0 <= band[1]:
        return Heave(False, s0, None, f0, z0, why=f"the heave mode ({f0:.2f} Hz) is outside the band "
                                                  f"{band[0]:.2f}–{band[1]:.2f} Hz: there the channel gives only "
                                                  "the share over the frequency squared")
    # the profile of s over the grid points whose least-squares cost is within HEAVE_LR (quadratic in s
    # at each, curvature 2a; its least-squares share moved by the same compensation), the cost in
    # units of its own Birge ratio when the fit leaves more than the output's noise (2 dof per bin)
    birge = max(1.0, c0 / max(2 * len(bins) - 3, 1))
    lo_s, hi_s = [], []
    for c, f, z, aa, bb, gg, gr in fits:
        room = HEAVE_LR * birge - (c - c0)
        if room >= 0 and aa > gg:
            centre = (bb - gr) / (aa - gg)
            half = np.sqrt(room / (2.0 * aa)) * aa / (aa - gg)
            lo_s.append(centre - half)
            hi_s.append(centre + half)
    # a compensation larger than σ is itself evidence of trouble: its size joins σ
    sd = float(np.hypot(0.5 * (max(hi_s) - min(lo_s)), s0 - b / a))
    if not sd <= MASS_SHARE_STD_LIMIT:
        return Heave(False, s0, sd, f0, z0, why=f"the mass share's 95 % profile interval is {min(lo_s):.2f}–"
                                                f"{max(hi_s):.2f} (σ {sd:.2f} beyond {MASS_SHARE_STD_LIMIT:g})")
    return Heave(True, float(s0), float(sd), float(f0), float(z0))
