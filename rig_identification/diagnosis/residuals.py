"""Where a fitted diagnosis model and the recording disagree (the method:
:mod:`~rig_identification.diagnosis.selection`).

:func:`channel_residuals`: the residual per channel — gyro and accelerometer (band-passed,
with the mean levels), the Newton–Euler equation errors (torque, force) and each load cell
(the tension correction that best explains them, least squares).  :func:`synchronous_rms`:
each channel time-synchronously averaged over the exciter's revolutions (the part locked to
the forcing, the noise averaged down by about √(revolutions)).  :func:`locate`: the spectral
lines, bands and times of the mismatch, named (forcing, its harmonics, the rig's modes);
:func:`unexplained` the JSON of it; :func:`effective_samples` the independent samples of a
band-passed residual.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import welch

from ..model.modes import natural_modes
from .model_extension import ROT, TR, Fit, Model
from .window import WRENCH_SCALE, Window

SYNC_BINS = 36        # exciter-phase bins of the time-synchronous average (10° each)
SYNC_MIN_REVOLUTIONS = 10   # fewer exciter revolutions in the window: no synchronous residual


def channel_residuals(model: Model, fit: Fit) -> dict:
    """Residual time series (N,) per channel: gyro and accelerometer (band-passed, plus
    the mean-level residual), torque and force (Newton–Euler equation errors, N·m and N),
    and each load cell (least-squares tension correction, N)."""
    w = model.w
    out = {}
    for k in range(3):
        out[ROT[k]] = fit.rot[:, k] + fit.dcg[k]
        out[TR[k]] = fit.tr[:, k] + fit.dca[k]
    # Newton–Euler equation errors, band-passed: torque = J α + ω×Jω − M − ΔM  (in-band)
    J = fit.J
    # torque residual from the output error: J (d/dt) of the rotational residual
    torque = np.gradient(fit.rot, w.t, axis=0) @ J.T + fit.dcm
    force = fit.tr * w.mass
    for k, a in enumerate("xyz"):
        out[f"torque_{a}"] = torque[:, k]
        out[f"force_{a}"] = force[:, k]
    # load cells: tension corrections δT that best explain the wrench residual
    wr = np.concatenate([force, torque], axis=1)                             # (N,6)
    dT = np.einsum("nij,nj->ni", w.tension_map, wr * WRENCH_SCALE)
    for i, name in enumerate(w.cable_names):
        out[f"load_cell_{name}"] = dT[:, i]
    return out


def rms(d: dict) -> dict:
    return {k: float(np.sqrt(np.mean(v**2))) for k, v in d.items()}


def exciter_phase(w: Window) -> np.ndarray | None:
    """The rotating exciter force's phase (N,) rad, unwrapped, from its two components in the
    exciter's spin plane (``f_exc`` in the exciter frame); NaN where the force is below a
    fifth of its median magnitude (stopped, spinning up).  None without a rotating exciter:
    no exciter, or fewer than :data:`SYNC_MIN_REVOLUTIONS` turns in the window."""
    fe = w.f_exc @ w.exc_rot[:, :2]
    mag = np.linalg.norm(fe, axis=1)
    if not np.any(mag > 0):
        return None
    ph = np.unwrap(np.arctan2(fe[:, 1], fe[:, 0]))
    ph[mag < 0.2 * np.median(mag)] = np.nan
    ok = np.isfinite(ph)
    if ok.sum() < 2 or abs(ph[ok][-1] - ph[ok][0]) < 2 * np.pi * SYNC_MIN_REVOLUTIONS:
        return None
    return ph


def synchronous_rms(series: dict, phase: np.ndarray, bins: int = SYNC_BINS) -> dict:
    """RMS per channel of the time-synchronous average of its residual (N,): the mean over the
    exciter's revolutions in ``bins`` bins of its phase (N,) rad (NaN: left out), RMS over the
    bins weighted by their samples.  What is locked to the forcing (its frequency, harmonics
    and the mean) stays; the sensor noise and the free modes average out, by about √(number
    of revolutions) for the noise: the model error under a noise floor becomes measurable.
    Source: Braun, "The extraction of periodic waveforms by time domain averaging", Acustica
    32 (1975); McFadden, Mech. Syst. Signal Process. 1 (1987) 83–95."""
    from scipy.stats import binned_statistic
    ok = np.isfinite(phase)
    th = np.mod(phase[ok], 2 * np.pi)
    names = list(series)
    means = binned_statistic(th, [np.asarray(series[k])[ok] for k in names], "mean", bins=bins,
                             range=(0.0, 2 * np.pi)).statistic                      # (channels, bins)
    n = np.histogram(th, bins=bins, range=(0.0, 2 * np.pi))[0]
    filled = n > 0
    return {k: float(np.sqrt(np.sum(n[filled] * means[i, filled] ** 2) / n[filled].sum()))
            for i, k in enumerate(names)}


def synchronous(model: "Model", ch: dict) -> tuple:
    """(synchronous RMS per channel or None, revolutions or None) of a window's residuals."""
    ph = exciter_phase(model.w)
    if ph is None:
        return None, None
    ok = np.isfinite(ph)
    return synchronous_rms(ch, ph), float(abs(ph[ok][-1] - ph[ok][0]) / (2 * np.pi))


def locate(model: Model, fit: Fit, rig, inertia) -> dict:
    """Where the residuals of the fit show a mismatch: in time (RMS per tenth of the window,
    and while the exciter runs vs not), in frequency (Welch peaks, each named: the forcing,
    its harmonics, a natural frequency of the rig, or unexplained), whiteness (Ljung–Box on
    the residual decimated to the band) and correlation with the inputs and states."""
    from scipy.stats import chi2 as _chi2
    w = model.w
    ch = channel_residuals(model, fit)
    fs = model.fs
    lo, hi = model.band
    # exciter frequency from the exciter force direction's rotation
    f_exc = None
    if np.any(w.f_exc):
        ang = np.unwrap(np.arctan2(w.f_exc[:, 1], w.f_exc[:, 0]))
        on = np.linalg.norm(w.f_exc, axis=1) > 0.5 * np.percentile(np.linalg.norm(w.f_exc, axis=1), 95)
        if on.sum() > 10:
            f_exc = abs(float(np.polyfit(w.t[on], ang[on], 1)[0])) / (2 * np.pi)
    try:
        k = rig.cable_stiffness if np.isfinite(rig.cable_stiffness).all() else None
        nat = [m.frequency for m in natural_modes(rig, rig.mass, rig.require_cg(), inertia, k)]
    except Exception:  # noqa: BLE001 — the modes are an aid to naming peaks, not required
        nat = []
    states = {"omega_x": w.omega[:, 0], "omega_y": w.omega[:, 1], "omega_z": w.omega[:, 2],
              "|omega|": np.linalg.norm(w.omega, axis=1), "v_x": w.v[:, 0], "v_y": w.v[:, 1], "v_z": w.v[:, 2],
              "|v|": np.linalg.norm(w.v, axis=1)}
    for i, n in enumerate(w.cable_names):
        states[f"tension_{n}"] = w.tensions[:, i]
    if f_exc is not None:
        states["exciter_force_x"] = w.f_exc[:, 0]
        states["exciter_force_y"] = w.f_exc[:, 1]
    filt_states = {k: model.filt(v - v.mean()) for k, v in states.items()}
    step = max(1, int(fs / (2 * hi)))
    out = {}
    for name, r in ch.items():
        rr = r - r.mean()
        tenths = np.array_split(rr, 10)
        seg = [float(np.sqrt(np.mean(x**2))) for x in tenths]
        f, P = welch(rr, fs=fs, nperseg=min(len(rr), int(2 ** np.ceil(np.log2(20 * fs)))))
        inb = (f >= lo) & (f <= hi)
        peaks = []
        if inb.sum() > 3:
            Pi = P[inb]
            fl = np.median(Pi)
            order = np.argsort(Pi)[::-1]
            for i in order[:40]:
                if Pi[i] < 10 * fl or len(peaks) >= 3:
                    break
                fr = float(f[inb][i])
                if any(abs(fr - p["hz"]) < 0.1 for p in peaks):
                    continue
                peaks.append({"hz": round(fr, 3), "power_over_floor": round(float(Pi[i] / fl), 1),
                              "is": _name_peak(fr, f_exc, nat)})
        d = rr[::step]
        nlag = 10
        ac = np.array([np.corrcoef(d[:-L], d[L:])[0, 1] for L in range(1, nlag + 1)])
        q = len(d) * (len(d) + 2) * np.sum(ac**2 / (len(d) - np.arange(1, nlag + 1)))
        corr = sorted(((abs(float(np.corrcoef(rr, s)[0, 1])), k)
                       for k, s in filt_states.items() if np.std(s) > 0), reverse=True)[:3]
        out[name] = {"rms": float(np.sqrt(np.mean(r**2))), "mean": float(r.mean()),
                     "rms_by_tenth": [round(x, 9) for x in seg],
                     "grows_at": _grows(seg, w.t),
                     "peaks": peaks, "whiteness_p": float(_chi2.sf(q, nlag)),
                     "correlates_with": [{"signal": k, "correlation": round(c, 3)} for c, k in corr]}
    return out


def _name_peak(fr, f_exc, nat) -> str:
    if f_exc:
        for h in range(1, 6):
            if abs(fr - h * f_exc) < 0.03 * h * f_exc + 0.02:
                return "forcing" if h == 1 else f"forcing harmonic {h}"
    for i, fn in enumerate(nat):
        if abs(fr - fn) < 0.03 * fn + 0.02:
            return f"natural frequency {fn:.3f} Hz"
    if f_exc and nat:
        for fn in nat:
            if abs(fr - (fn + f_exc)) < 0.04 or abs(fr - abs(fn - f_exc)) < 0.04:
                return "intermodulation of the forcing and a mode"
    return "unexplained (no rigid-body mode or forcing harmonic)"


def _grows(seg, t) -> str | None:
    seg = np.asarray(seg)
    med = np.median(seg)
    if med <= 0:
        return None
    i = int(np.argmax(seg))
    if seg[i] > 2 * med:
        T = t[-1] - t[0]
        return f"{i * T / 10:.0f}–{(i + 1) * T / 10:.0f} s into the window ({seg[i] / med:.1f}× the median RMS)"
    return None


def effective_samples(r: np.ndarray) -> float:
    """Number of independent samples in a residual series (N, k): N over the integrated
    autocorrelation time τ = 1 + 2 Σ ρ_k, summed over the initial positive sequence of
    lag pairs (Geyer, Statistical Science 7, 1992), averaged over the columns."""
    n = len(r)
    taus = []
    for x in np.atleast_2d(r.T):
        x = x - x.mean()
        f = np.fft.rfft(x, 2 * n)
        ac = np.fft.irfft(f * np.conj(f))[:n]
        ac = ac / ac[0]
        pairs = ac[1:-1:2] + ac[2::2]
        stop = np.argmax(pairs <= 0) if np.any(pairs <= 0) else len(pairs)
        taus.append(max(1.0, 1.0 + 2.0 * (ac[1:2 * stop + 1].sum())))
    return float(n / np.mean(taus))



def unexplained(located: dict, duration: float, limit: int = 6) -> list[dict]:
    """Where the rigid-body fit's residuals show the mismatch, from :func:`locate`'s
    analysis: one entry per spectral line of a channel's residual (the largest first)
    ``{"channel", "band_hz": [lo, hi] Hz, "time_s": [start, end] s from the window's start,
    "size": power over the residual's median in-band level, "is": what the frequency is}``;
    a channel with no line but a residual that is not white (Ljung–Box p < 1e-3) gives one
    entry over the whole band (size: its RMS).  ``time_s`` is the tenth of the window where
    the channel's residual is largest when that is over twice the median tenth, else the
    whole window.  At most ``limit`` entries."""
    out = []
    for ch, a in located.items():
        seg = np.asarray(a.get("rms_by_tenth") or [0.0])
        med = float(np.median(seg))
        i = int(np.argmax(seg))
        span = [i * duration / 10, (i + 1) * duration / 10] if med > 0 and seg[i] > 2 * med else [0.0, duration]
        for pk in a.get("peaks", []):
            out.append({"channel": ch, "band_hz": [round(max(pk["hz"] - 0.05, 0.0), 3), round(pk["hz"] + 0.05, 3)],
                        "time_s": [round(x, 1) for x in span], "size": pk["power_over_floor"], "is": pk["is"]})
        if not a.get("peaks") and a.get("whiteness_p", 1.0) < 1e-3:
            out.append({"channel": ch, "band_hz": None, "time_s": [round(x, 1) for x in span],
                        "size": a.get("rms"), "is": "a coloured residual (not white)"})
    out.sort(key=lambda e: -(e["size"] or 0.0) if e["band_hz"] is not None else 0.0)
    return out[:limit]
