"""Plots and files of ``rig-identify diagnose --report DIR``: the residuals of every channel
before and after the selected effects, in time and as spectra (Welch, scipy), and the
diagnosis JSON.  Written atomically (:func:`~rig_identification.atomic.atomic_directory`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

GROUPS = {
    "gyro": (["gyro_x", "gyro_y", "gyro_z"], "rad/s"),
    "accelerometer": (["accel_x", "accel_y", "accel_z"], "m/s²"),
    "torque": (["torque_x", "torque_y", "torque_z"], "N·m"),
    "force": (["force_x", "force_y", "force_z"], "N"),
}


def write_report(diag, out: str | Path, title: str = "diagnosis") -> Path:
    """Write ``DIR/diagnosis.json``, ``DIR/residuals_<group>.png`` (time series) and
    ``DIR/spectra_<group>.png`` (residual spectra) before/after, and ``DIR/index.html``.
    Returns the folder.  Replaces an existing folder atomically."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.signal import welch

    from .atomic import atomic_directory

    ser = diag.series
    t, fs = ser["t"], ser["fs"]
    groups = dict(GROUPS)
    cells = [k for k in ser["before"] if k.startswith("load_cell_")]
    if cells:
        groups["load cells"] = (cells, "N")
    with atomic_directory(out) as tmp:
        (tmp / "diagnosis.json").write_text(json.dumps(diag.to_dict(), indent=1))
        imgs = []
        for g, (chs, unit) in groups.items():
            slug = g.replace(" ", "_")
            fig, axes = plt.subplots(len(chs), 1, figsize=(10, 1.9 * len(chs) + 0.6), sharex=True, squeeze=False)
            for ax, ch in zip(axes[:, 0], chs):
                ax.plot(t, ser["before"][ch], lw=0.5, color="tab:red", label="before (rigid-body model)")
                ax.plot(t, ser["after"][ch], lw=0.5, color="tab:blue", label="after (with the effects found)")
                ax.set_ylabel(f"{ch}\n{unit}", fontsize=8)
                ax.grid(alpha=0.3)
            axes[0, 0].legend(fontsize=8, loc="upper right")
            axes[-1, 0].set_xlabel("time in the window, s")
            fig.suptitle(f"{title}: {g} residuals")
            fig.tight_layout()
            fig.savefig(tmp / f"residuals_{slug}.png", dpi=90)
            plt.close(fig)
            fig, axes = plt.subplots(1, len(chs), figsize=(4 * len(chs), 3.2), squeeze=False)
            for ax, ch in zip(axes[0], chs):
                for key, color in (("before", "tab:red"), ("after", "tab:blue")):
                    x = ser[key][ch]
                    f, P = welch(x - x.mean(), fs=fs, nperseg=min(len(x), int(2 ** np.ceil(np.log2(20 * fs)))))
                    ax.semilogy(f, np.sqrt(P), color=color, lw=0.8, label=key)
                ax.set_xlim(0, min(fs / 2, 4 * diag.band[1]))
                ax.axvspan(*diag.band, color="0.9", zorder=0)
                ax.set_title(ch, fontsize=9)
                ax.set_xlabel("Hz")
                ax.grid(alpha=0.3)
            axes[0, 0].set_ylabel(f"{unit}/√Hz")
            axes[0, 0].legend(fontsize=8)
            fig.suptitle(f"{title}: {g} residual spectra (grey: the fit's band)")
            fig.tight_layout()
            fig.savefig(tmp / f"spectra_{slug}.png", dpi=90)
            plt.close(fig)
            imgs += [f"residuals_{slug}.png", f"spectra_{slug}.png"]
        d = diag.to_dict()
        rows = "".join(f"<tr><td>{e['name']}</td><td>{json.dumps(e['parameters'])}</td>"
                       f"<td>{json.dumps(e['parameters_std'])}</td>"
                       f"<td>{e['evidence']['likelihood_ratio']:.1f}</td></tr>" for e in d["effects"])
        s0, s1 = d["residual_rms_synchronous_before"], d["residual_rms_synchronous_after"]
        sync = s0 is not None and s1 is not None
        rms = "".join(f"<tr><td>{k}</td><td>{d['residual_rms_before'][k]:.4g}</td>"
                      f"<td>{d['residual_rms_after'][k]:.4g}</td>"
                      + (f"<td>{s0[k]:.4g}</td><td>{s1[k]:.4g}</td>" if sync else "") + "</tr>"
                      for k in d["residual_rms_before"])
        sync_head = ("<th>synchronous before</th><th>synchronous after</th>" if sync else "")
        sync_note = (f"<p>synchronous: the residual averaged over {d['synchronous_revolutions']:.0f} exciter "
                     "revolutions (what is locked to the forcing; the noise averaged down by about √revolutions)"
                     "</p>" if sync else "")
        body = "".join(f'<p><img src="{i}" alt="{i}"></p>' for i in imgs)
        verdict = ("mismatch: " + ", ".join(e["name"] for e in d["effects"])) if d["mismatch"] \
            else "no significant mismatch"
        (tmp / "index.html").write_text(
            f"<!doctype html><html><head><meta charset='utf-8'><title>{title}</title></head><body>"
            f"<h1>{title}</h1><p><b>{verdict}</b></p>"
            f"<table border=1><tr><th>effect</th><th>parameters</th><th>std</th><th>likelihood ratio</th></tr>"
            f"{rows}</table><h2>Residual RMS per channel</h2><table border=1><tr><th>channel</th><th>before</th>"
            f"<th>after</th>{sync_head}</tr>{rms}</table>{sync_note}{body}</body></html>")
    return Path(out)
