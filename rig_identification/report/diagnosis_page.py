"""Plots and files of ``rig-identify diagnose --report DIR``: the residuals of every channel
before and after the selected effects, in time and as spectra (Welch, scipy), the effects with
their parameters in SI units, and the diagnosis JSON (null, never NaN).  Written atomically
(:func:`~rig_identification.io.atomic.atomic_directory`); figures with matplotlib's object API
(Agg, no pyplot state).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.signal import welch

from ..io.atomic import atomic_directory
from .diagnosis import channel_unit, diagnosis_json, effects_table
from .figures import figure, robust_limit
from .html import esc, json_safe, num, page, table

GROUPS = {
    "gyro": (["gyro_x", "gyro_y", "gyro_z"], "rad/s"),
    "accelerometer": (["accel_x", "accel_y", "accel_z"], "m/s²"),
    "torque": (["torque_x", "torque_y", "torque_z"], "N·m"),
    "force": (["force_x", "force_y", "force_z"], "N"),
}
COLORS = {"before": "tab:red", "after": "tab:blue"}
LABELS = {"before": "before (rigid-body model)", "after": "after (with the effects found)"}


def residual_figure(path: Path, t: np.ndarray, ser: dict, chs: list[str], unit: str, title: str) -> None:
    """Residuals of the channels ``chs`` before/after, one panel each, y-limits robust (the
    99.9th percentile, so a start-up transient does not flatten the rest)."""
    fig = figure(10, 1.9 * len(chs) + 1.0)
    axes = fig.subplots(len(chs), 1, sharex=True, squeeze=False)[:, 0]
    for ax, ch in zip(axes, chs):
        for key in ("before", "after"):
            ax.plot(t, ser[key][ch], lw=0.5, color=COLORS[key], label=LABELS[key])
        lim = robust_limit(np.concatenate([ser["before"][ch], ser["after"][ch]]))
        ax.set_ylim(-lim, lim)
        ax.set_ylabel(f"{ch}, {unit}", fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time in the window, s")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize=8)
    fig.suptitle(f"{title}: residuals")
    fig.savefig(path, dpi=90)


def spectra_figure(path: Path, ser: dict, fs: float, band: tuple, chs: list[str], unit: str, title: str) -> None:
    """Amplitude spectra (Welch) of the residuals before/after over the fit band (a little
    beyond), the band shaded."""
    fig = figure(4 * len(chs), 3.6)
    axes = fig.subplots(1, len(chs), squeeze=False)[0]
    lo, hi = float(band[0]), float(band[1])
    f0, f1 = max(0.0, lo - 0.3 * (hi - lo)), min(fs / 2, hi + 0.3 * (hi - lo))
    for ax, ch in zip(axes, chs):
        shown = []
        for key in ("before", "after"):
            x = np.asarray(ser[key][ch], float)
            f, P = welch(x - x.mean(), fs=fs, nperseg=min(len(x), int(2 ** np.ceil(np.log2(20 * fs)))))
            ax.semilogy(f, np.sqrt(P), color=COLORS[key], lw=0.8, label=LABELS[key])
            shown.append(np.sqrt(P[(f >= f0) & (f <= f1)]))
        level = np.concatenate(shown)
        level = level[np.isfinite(level) & (level > 0)]
        if level.size:
            ax.set_ylim(0.3 * float(np.percentile(level, 2)), 3 * float(level.max()))
        ax.set_xlim(f0, f1)
        ax.axvspan(lo, hi, color="0.9", zorder=0, label="fit band")
        ax.set_title(ch, fontsize=9)
        ax.set_xlabel("frequency, Hz")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"{unit}/√Hz")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=3, fontsize=8)
    fig.suptitle(f"{title}: residual spectra")
    fig.savefig(path, dpi=90)


def rms_table(d: dict) -> str:
    """Residual RMS per channel before/after (and synchronous with the exciter when there)."""
    s0, s1 = d.get("residual_rms_synchronous_before"), d.get("residual_rms_synchronous_after")
    sync = s0 is not None and s1 is not None
    rows = []
    for k, before in d["residual_rms_before"].items():
        row = [k, channel_unit(k), num(before, ".4g"), num(d["residual_rms_after"].get(k), ".4g")]
        if sync:
            row += [num(s0.get(k), ".4g"), num(s1.get(k), ".4g")]
        rows.append(row)
    head = ["channel", "unit", "before", "after"] + (["synchronous before", "synchronous after"] if sync else [])
    out = table(head, rows, text_cols=(1,))
    if sync:
        n = num(d.get("synchronous_revolutions"), ".0f")
        out += (f'<p class="note">Synchronous: the residual averaged over {n} exciter revolutions'
                " (what is locked to the forcing; the noise averaged down by about "
                "√revolutions).</p>")
    return out


def write_report(diag, out: str | Path, title: str = "diagnosis") -> Path:
    """Write ``DIR/diagnosis.json``, ``DIR/residuals_<group>.png`` (time series) and
    ``DIR/spectra_<group>.png`` (residual spectra) before/after, and ``DIR/index.html``.
    Returns the folder.  Replaces an existing folder atomically."""
    ser = diag.series
    t, fs = ser["t"], ser["fs"]
    groups = dict(GROUPS)
    cells = [k for k in ser["before"] if k.startswith("load_cell_")]
    if cells:
        groups["load cells"] = (cells, "N")
    d = json_safe(diagnosis_json(diag.to_dict()))
    with atomic_directory(out) as tmp:
        (tmp / "diagnosis.json").write_text(json.dumps(d, indent=1, allow_nan=False))
        imgs = []
        for g, (chs, unit) in groups.items():
            slug = g.replace(" ", "_")
            residual_figure(tmp / f"residuals_{slug}.png", t, ser, chs, unit, f"{title}: {g}")
            spectra_figure(tmp / f"spectra_{slug}.png", ser, fs, diag.band, chs, unit, f"{title}: {g}")
            imgs += [(f"residuals_{slug}.png", f"{g} residuals"), (f"spectra_{slug}.png", f"{g} residual spectra")]
        verdict = ("Mismatch: the rigid-body model does not explain the recording; the effects below explain it "
                   "(best first)." if d["mismatch"] else "No significant mismatch: the rigid-body model explains "
                   "the recording.")
        parts = [f"<h1>{esc(title)}</h1>", f'<p class="verdict {"model_error" if d["mismatch"] else "ok"}">'
                 f"<b>{esc(verdict)}</b></p>"]
        if d["effects"]:
            parts.append(effects_table(d["effects"], "effects-table"))
        parts.append("<h2>Residual RMS per channel</h2>" + rms_table(d))
        parts.extend(f'<p class="warn">warning: {esc(w)}</p>' for w in d.get("warnings") or [])
        parts.extend(f'<p><img src="{src}" alt="{esc(alt)}"></p>' for src, alt in imgs)
        (tmp / "index.html").write_text(page(title, parts), encoding="utf-8")
    return Path(out)
