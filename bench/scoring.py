"""What the benches that judge fits against the simulator's truth share (bench_trust.py,
bench_any_rig.py): the scale each entry's error is judged on, each reported entry's error % and
error/σ, the rows every table prints the same way
(a rig the simulator could not make, a recording the tool refused), the rig as a lab surveys it
(errors concealed in rig.yaml and the load cells, each of the survey's σ), and the run over worker
processes that says each recording on stderr as it is done and keeps what it measured.
"""
from __future__ import annotations

import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from rig_identification.io.rig import Rig
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import entry_scales


def surveyed(rig: Rig, rng: np.random.Generator, std: float | None = None, cg_std: float = 0.0) -> Rig:
    """``rig`` as the lab's rig.yaml has it: every anchor coordinate and cable length off by
    N(0, σ) m (σ: rig.yaml's survey, or ``std``, which becomes its survey σ), the mass by N(0, its
    survey σ), the CG by N(0, ``cg_std``) m per coordinate (a static test's error)."""
    sv = rig.survey if std is None else replace(rig.survey, anchors=std, lengths=std)
    cables = tuple(replace(c, ceiling_anchor=c.ceiling_anchor + rng.normal(0, sv.anchors, 3),
                           body_anchor=c.body_anchor + rng.normal(0, sv.anchors, 3),
                           length=c.length + rng.normal(0, sv.lengths)) for c in rig.cables)
    cg = rig.center_of_gravity
    return replace(rig, cables=cables, survey=sv, mass=rig.mass + rng.normal(0, sv.mass_std(rig.mass)),
                   center_of_gravity=None if cg is None else cg + rng.normal(0, cg_std, 3))


def load_cell_errors(cables: int, share: float, rng: np.random.Generator) -> list[dict]:
    """The effects (:mod:`~rig_identification.model.effects` ``load_cell_scale``) that give each of
    the ``cables`` load cells (named c0, c1, … as :func:`~rig_identification.design.scenarios.random_experiment`
    names them) a gain off by N(0, ``share``): a calibrated load cell's accuracy class."""
    return [{"name": "load_cell_scale", "cable": f"c{i}", "scale": float(1 + rng.normal(0, share))}
            for i in range(cables)]


def score_entries(inertia: np.ndarray, std: np.ndarray, undetermined, truth: dict) -> dict:
    """Each entry a fit gives — ``inertia`` (6,) kg·m² and its σ ``std`` (6,) in KEYS order, its
    ``undetermined`` entries left out — against ``truth`` (``inertia_about_cg``: KEYS -> kg·m²):
    {key: {"error_pct" (of :func:`entry_scales`), "z" (error/σ; inf for σ 0), "rel_std", "finite"}}."""
    th = np.array([truth[k] for k in KEYS])
    scale = entry_scales(th)
    out = {}
    for k, x, s, ref, t in zip(KEYS, np.asarray(inertia, float), np.asarray(std, float), scale, th):
        if k in undetermined:
            continue
        out[k] = {"error_pct": float(100 * (x - t) / ref), "z": float((x - t) / s) if s > 0 else float("inf"),
                  "rel_std": float(s / ref), "finite": bool(np.isfinite(x) and np.isfinite(s))}
    return out


def worst(entries: dict) -> tuple[float | None, float | None]:
    """(largest |error %|, largest |error/σ|) over the finite entries of :func:`score_entries`."""
    fin = [e for e in entries.values() if e["finite"]]
    return (max((abs(e["error_pct"]) for e in fin), default=None),
            max((abs(e["z"]) for e in fin), default=None))


def print_unscored(r: dict, label: str, width: int) -> bool:
    """Print the row of a rig the simulator could not make ("skipped") or a recording the tool
    refused, after ``label``; True when ``r`` was one of them."""
    if "skipped" in r:
        print(f"{label} skipped: {r['skipped'][:90]}")
        return True
    if r.get("verdict") == "refused":
        print(f"{label} {'refused':{width}s} {r['error'][:100]}")
        return True
    return False


def run_jobs(job, args: list, procs: int, json_path: str | None, label) -> list[dict]:
    """``job`` over ``args`` in ``procs`` worker processes, in order: each row said on stderr as
    it is done (``label(row)``, its verdict, the time so far: a sweep takes tens of minutes)
    and, with ``json_path``, all rows so far written there after each (an interrupted sweep
    keeps what it measured).  Returns the rows."""
    t0 = time.perf_counter()
    rows: list[dict] = []
    with ProcessPoolExecutor(procs) as ex:
        for r in ex.map(job, args):
            rows.append(r)
            print(f"done {len(rows)}/{len(args)}: {label(r)}: {r.get('verdict', 'skipped')} "
                  f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
            if json_path:
                Path(json_path).write_text(json.dumps(rows, indent=1))
    return rows
