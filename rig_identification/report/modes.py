"""The report's natural-modes table of one recording: each mode from the geometry
(:func:`~rig_identification.model.modes.natural_modes` with rig.yaml, the identified tensor and, when known, the true
one) beside the nearest free-vibration peak of the recording within 10 %
(:func:`~rig_identification.model.modes.estimate_modes`; each peak used once)."""
from __future__ import annotations

import numpy as np

from ..estimation.inertia_result import InertiaResult
from ..io.recording import Recording
from ..io.rig import inertia_tensor
from ..model.dynamics import SimulationError
from ..model.modes import estimate_modes, natural_modes
from .html import MISSING, esc, num, table


def modes_section(rec: Recording, result: InertiaResult, truth: dict | None, cg_source: str | None = None
                  ) -> tuple[str, list[str], dict]:
    """HTML, notes and data (for report.json) of the modes table of ``rec``.  Frequencies Hz;
    mode shapes in world axes.  The geometric modes are the rig's with the result's mass, CG and
    tensor (the point the tensor is about; ``cg_source``: where that CG came from, None: rig.yaml);
    they need the whole tensor: when it is not determined, only the recording's are listed."""
    rig = rec.rig
    if all(c.stiffness is not None for c in rig.cables):
        k, kname = rig.cable_stiffness, "spring cables (rig.yaml stiffness)"
    else:
        k, kname = None, "inextensible cables"
    notes: list[str] = []
    data = {"cable_model": kname, "modes": [], "unmatched_estimated_hz": []}
    geo, why = [], ""
    if result.undetermined or not np.all(np.isfinite(result.inertia)):
        why = "the tensor is not determined"
    else:
        try:
            geo = natural_modes(rig, result.mass, result.center_of_gravity, result.inertia, k)
        except SimulationError as e:
            why = str(e)
    geo_t = None
    if truth is not None and geo:
        try:
            geo_t = natural_modes(rig, result.mass, result.center_of_gravity, inertia_tensor(truth["inertia_about_cg"]),
                                  k)
        except SimulationError:
            geo_t = None
    est = estimate_modes(rec)
    notes += est.warnings
    used = set()
    head = ["geometry Hz (identified J)"] + (["geometry Hz (true J)"] if geo_t else []) + \
        ["mode shape (world axes)", "recording Hz", "difference %", "damping ratio", "seen on"]
    rows = []
    for n, m in enumerate(geo):
        cand = [e for e in est.modes if id(e) not in used]
        best = min(cand, key=lambda e: abs(e.frequency - m.frequency), default=None)
        row = [num(m.frequency, ".4f")] + ([num(geo_t[n].frequency, ".4f")] if geo_t else []) + [m.description]
        item = {"geometric_hz": m.frequency, "geometric_true_hz": geo_t[n].frequency if geo_t else None,
                "description": m.description, "estimated_hz": None, "difference_percent": None,
                "damping_ratio": None, "axes": None}
        if best is not None and abs(best.frequency - m.frequency) <= 0.1 * m.frequency:
            used.add(id(best))
            diff = 100 * (best.frequency - m.frequency) / m.frequency
            row += [num(best.frequency, ".4f"), num(diff, "+.2f"), num(best.damping_ratio, ".4f"), best.axes]
            item.update(estimated_hz=best.frequency, difference_percent=diff, damping_ratio=best.damping_ratio,
                        axes=best.axes)
        else:
            row += ["not seen", MISSING, MISSING, MISSING]
        rows.append(row)
        data["modes"].append(item)
    for e in est.modes:
        if id(e) not in used:
            rows.append([MISSING] + ([MISSING] if geo_t else []) + ["(no geometric mode)", num(e.frequency, ".4f"),
                                                                   MISSING, num(e.damping_ratio, ".4f"), e.axes])
            data["unmatched_estimated_hz"].append(e.frequency)
    data["exciter_frequency_hz"] = est.exciter_frequency
    fex = "" if est.exciter_frequency is None else \
        f" Exciter at {est.exciter_frequency:.4f} Hz (excluded with its harmonics)."
    where = cg_source or "rig.yaml body.center_of_gravity"
    cg = ", ".join(f"{x:.4f}" for x in result.center_of_gravity)
    intro = f"<p>Model: mass {result.mass:g} kg, CG [{cg}] m ({esc(where)}), {esc(kname)}.{esc(fex)}</p>"
    data["center_of_gravity_source"] = where
    if why:
        intro += f"<p>Geometric modes: not available ({esc(why)}).</p>"
    text = [i for i, h in enumerate(head) if h in ("mode shape (world axes)", "seen on")]
    body = table(head, rows, text_cols=text) if rows else "<p>No free-vibration peak found in the recording.</p>"
    return intro + body, notes, data


__all__ = ["modes_section"]
