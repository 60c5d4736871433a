"""The thesis's 17 case studies, simulated noise-free, identified by our method and by the
thesis's (``--model thesis``), beside the errors the thesis reported (its chapter 4).

Error convention: % of the entry for moments, % of the largest moment for products (the
thesis printed absolute errors, ±, for products whose true value is 0; those are shown as
they were printed, in kg·m², marked "abs").
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..estimation.gyro_fit import IdentificationError
from ..estimation.inertia_result import compare_to_truth
from ..io.export import ORDER
from ..io.recording import Recording
from ..io.verdict import KEYS
from ..model.experiment import load_experiment
from ..model.parametrisation import PAIRS
from ..model.simulator import simulate
from .offline import identify_recording

CASES = Path(__file__).resolve().parents[2] / "config" / "cases"


def cases_dir() -> Path:
    """config/cases in the repository, or in the colcon install's share directory."""
    if CASES.is_dir():
        return CASES
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory("rig_identification")) / "config" / "cases"


def run_case(name: str) -> dict:
    """Simulate one case (its config as is) and identify it with both models.

    Returns {"case", "ours": {key: error %}, "thesis_model": {...}, "thesis_reported": {...},
    "notes"}; a model that cannot produce an estimate gives its error message instead.
    """
    exp = load_experiment(cases_dir() / f"{name}.yaml")
    sim = simulate(exp)
    rec = Recording(sim.rig, sim.sensors, sim.truth, f"{name} (simulated)")   # the name in error messages
    th = exp.thesis or {}
    window = th.get("identification_window")
    start, end = (window if window else (None, None))
    guess = np.asarray(th.get("initial_guess", [np.nan] * 6), float) * np.array([1, -1, -1, 1, -1, 1])
    out = {"case": name, "description": exp.description}
    for key, model in (("ours", "pem"), ("thesis_model", "thesis")):
        try:
            res = identify_recording(rec, start=start, end=end, model=model,
                                     initial_guess=None if np.isnan(guess).any() else guess)
            out[key] = {k: c["error_percent"] for k, c in compare_to_truth(res, sim.truth).items()}
        except (IdentificationError, ValueError) as e:
            out[key] = str(e)
    rep = th.get("reported_error_percent")
    tru = sim.truth["inertia_about_cg"]
    if rep is not None:
        out["thesis_reported"] = {k: (float(rep[i][j]), "abs" if (i != j and tru[k] == 0) else "%")
                                  for k, (i, j) in zip(KEYS, PAIRS)}
    return out


def print_table(rows: list[dict]) -> None:
    print(f"{'case':7s} {'entry':5s} {'thesis reported':>16s} {'--model thesis':>15s} {'ours':>10s}")
    for r in rows:
        for n, k in enumerate(ORDER):   # moments, then products: the order of every table
            rep = r.get("thesis_reported", {}).get(k)
            rep_s = "-" if rep is None else (f"±{rep[0]:.2f} kg·m²" if rep[1] == "abs" else f"{rep[0]:.2f} %")
            cols = []
            for key in ("thesis_model", "ours"):
                v = r[key]
                cols.append(f"{v[k]:+.4f} %" if isinstance(v, dict) else ("n/a" if n else "fails"))
            print(f"{r['case']:7s} {k:5s} {rep_s:>16s} {cols[0]:>15s} {cols[1]:>10s}")
        for key in ("thesis_model", "ours"):
            if isinstance(r[key], str):
                print(f"{'':7s} {key}: {r[key]}")


def print_summary(rows: list[dict]) -> None:
    """One line per model: the largest |error| % of each case (of the entry for moments, of
    the largest moment for products), or why the case gave no estimate."""
    for key, label in (("ours", "ours"), ("thesis_model", "--model thesis")):
        parts = []
        for r in rows:
            v = r[key]
            parts.append(f"{r['case']} {max(abs(x) for x in v.values()):.3f}" if isinstance(v, dict)
                         else f"{r['case']} no estimate")
        print(f"largest error per case, {label} (%): " + ", ".join(parts))

