"""The thesis's 17 case studies, simulated noise-free, identified by the rig model (ours) and by
the thesis's own model and estimator, beside the errors the thesis reported (its chapter 4).

Ours is the rig model of ``rig-identify inertia``
(:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`, without the diagnosis: the
recordings are noise-free, so every channel's noise, estimated from the data, is at rounding
level) on the cases whose cables stretch (spring cables, as steel ropes are); the thesis's cases
with inextensible cables (01–09, 13) are outside its physics and say so.  The thesis's method
(:func:`~rig_identification.estimation.thesis_estimator.identify_inertia_thesis`) runs on every
case, on the tracker's and the preprocessor's output
(:func:`~rig_identification.estimation.tracker_replay.prepare_recording`).

Error convention: % of the entry for moments, % of the largest moment for products (the
thesis printed absolute errors, ±, for products whose true value is 0; those are shown as
they were printed, in kg·m², marked "abs").
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..estimation.gyro_fit import IdentificationError
from ..estimation.harmonic_start import box_tensor
from ..estimation.rig_record import RigFitError
from ..estimation.thesis_estimator import identify_inertia_thesis
from ..estimation.tracker import TrackerError
from ..estimation.tracker_replay import prepare_recording
from ..io.export import ORDER
from ..io.recording import Recording, RecordingError
from ..io.rig import RigError
from ..io.verdict import KEYS
from ..model.experiment import load_experiment
from ..model.parametrisation import PAIRS, entry_scales, from_tensor
from ..model.simulator import simulate
from .rig_model import fit_whole_recording

CASES = Path(__file__).resolve().parents[2] / "config" / "cases"

#: Why the rig model is not run on a case with inextensible cables.
INEXTENSIBLE = "outside the rig model: inextensible cables (its cables stretch, as steel ropes do)"


def cases_dir() -> Path:
    """config/cases in the repository, or in the colcon install's share directory."""
    if CASES.is_dir():
        return CASES
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory("rig_identification")) / "config" / "cases"


def errors_percent(entries: np.ndarray, truth: dict[str, Any]) -> dict[str, float]:
    """Each entry's error of the tensor ``entries`` (6,) kg·m² (:data:`~rig_identification.io.verdict.KEYS`
    order) against truth.yaml's ``inertia_about_cg``, % of the entry for moments and of the largest
    moment for products."""
    t = np.array([float(truth["inertia_about_cg"][k]) for k in KEYS])
    return {k: float(100 * e / s) for k, e, s in zip(KEYS, np.asarray(entries, float) - t, entry_scales(t))}


def run_case(name: str, duration: float | None = None) -> dict:
    """Simulate one case (its config as is, or cut to ``duration`` s) and identify it with the rig
    model and the thesis's method.

    Returns {"case", "description", "ours": {key: error %} or why there is none, "ours_verdict"
    (the rig model's, where it ran), "thesis_model": {key: error %} or its error message,
    "thesis_reported": {key: (value, "%" or "abs")}}.
    """
    exp = load_experiment(cases_dir() / f"{name}.yaml")
    if duration is not None:
        exp = replace(exp, duration=float(duration))
    sim = simulate(exp)
    rec = Recording(sim.rig, sim.sensors, sim.truth, Path(f"{name} (simulated)"))   # the name in error messages
    th = exp.thesis or {}
    window = th.get("identification_window")
    start, end = (window if window else (None, None))
    guess = np.asarray(th.get("initial_guess", [np.nan] * 6), float) * np.array([1, -1, -1, 1, -1, 1])
    out: dict[str, Any] = {"case": name, "description": exp.description}
    try:
        prep = prepare_recording(rec, start, end)
        fit = identify_inertia_thesis(prep.t, prep.gyro_body, prep.torque,
                                      box_tensor(rec.rig) if np.isnan(guess).any() else guess)
        out["thesis_model"] = errors_percent(from_tensor(fit.inertia), sim.truth)
    except (IdentificationError, RecordingError, RigError, TrackerError) as e:
        out["thesis_model"] = str(e)
    if exp.cable_model.type != "spring":
        out["ours"] = INEXTENSIBLE
    else:
        try:
            res = fit_whole_recording(rec, start=start, end=end, diagnose=False)
            out["ours"], out["ours_verdict"] = errors_percent(res.fit.inertia, sim.truth), res.verdict
        except (RigFitError, RecordingError, RigError) as e:
            out["ours"] = str(e)
    rep = th.get("reported_error_percent")
    tru = sim.truth["inertia_about_cg"]
    if rep is not None:
        out["thesis_reported"] = {k: (float(rep[i][j]), "abs" if (i != j and tru[k] == 0) else "%")
                                  for k, (i, j) in zip(KEYS, PAIRS)}
    return out


def print_table(rows: list[dict]) -> None:
    print(f"{'case':7s} {'entry':5s} {'thesis reported':>16s} {'thesis method':>15s} {'ours':>10s}")
    for r in rows:
        for n, k in enumerate(ORDER):   # moments, then products: the order of every table
            rep = r.get("thesis_reported", {}).get(k)
            rep_s = "-" if rep is None else (f"±{rep[0]:.2f} kg·m²" if rep[1] == "abs" else f"{rep[0]:.2f} %")
            cols = []
            for key in ("thesis_model", "ours"):
                v = r[key]
                cols.append(f"{v[k]:+.4f} %" if isinstance(v, dict) else ("-" if n else "none"))
            print(f"{r['case']:7s} {k:5s} {rep_s:>16s} {cols[0]:>15s} {cols[1]:>10s}")
        for key, label in (("thesis_model", "thesis method"), ("ours", "ours")):
            if isinstance(r[key], str):
                print(f"{'':7s} {label}: {r[key]}")
        if "ours_verdict" in r:
            print(f"{'':7s} ours: verdict {r['ours_verdict']} (noise-free: each channel's noise is rounding)")


def print_summary(rows: list[dict]) -> None:
    """One line per model: the largest |error| % of each case (of the entry for moments, of
    the largest moment for products), or why the case gave no estimate."""
    for key, label in (("ours", "ours (the rig model)"), ("thesis_model", "the thesis's method")):
        parts = []
        for r in rows:
            v = r[key]
            parts.append(f"{r['case']} {max(abs(x) for x in v.values()):.4f}" if isinstance(v, dict)
                         else f"{r['case']} none")
        print(f"largest error per case, {label} (%): " + ", ".join(parts))
