"""The model-error section of the report: what diagnosis found, or where the mismatch is.

``result.diagnosis`` (:func:`~rig_identification.pipeline.offline.with_diagnosis`) is one of two things:

* effects *named* (``effects`` non-empty, ``handled`` says how: removed from the data, added
  to the model): the fit with them passed its validation — a *finding*.  The page lists each
  effect in words with its parameters, their σ and SI units, the evidence, and the rigid-body
  fit beside the reported one;
* nothing named (``handled`` starts with "not: " and the reason): the rigid-body fit stays,
  ``unexplained`` says where its residual shows the mismatch (channel, band, time, size) and
  ``hypotheses`` holds diagnose's candidates — labelled as hypotheses, not findings.
"""
from __future__ import annotations

import math

import numpy as np

from ..diagnosis.distinguish import effect_name
from ..estimation.inertia_result import InertiaResult
from ..io.export import EFFECT_UNITS
from ..io.verdict import KEYS
from ..model.parametrisation import from_tensor
from .html import MISSING, Cell, esc, finite, num, table
from .mass import ORDER, SIGN, SYMBOL

# effect -> what it is, in words (effects.py's library)
EFFECT_TEXT = {
    "viscous_damping": "viscous damping: a force −c v on the CG and a moment −c ω on the body",
    "air_drag": "aerodynamic drag: a force −c |v| v and a moment −c |ω| ω",
    "coulomb_friction": "dry friction in the cable anchors' pivots, lumped on the body",
    "cable_elasticity": "the cables stretch more than rig.yaml says",
    "cable_mass": "the cables' mass: each lower half hangs on the body, outside the load cells",
    "body_mass": "the body is heavier than rig.yaml's body.mass",
    "exciter_rotor": "the exciter's rotor: its weight and spin angular momentum",
    "cg_offset": "the centre of gravity is not where rig.yaml puts it",
    "imu_offset": "the IMU is not where rig.yaml puts it",
    "imu_misalignment": "the IMU axes are turned against rig.yaml's imu.rpy",
    "sensor_delay": "a stream's stamps lag the IMU's",
    "gyro_bias": "a constant gyro bias",
    "accelerometer_bias": "a constant accelerometer bias",
    "load_cell_scale": "a load cell's gain is off",
    "gyroscopic_coupling": "the gyroscopic term ω × Jω",
    "gyro_bias_drift": "a drifting gyro bias (random walk)",
    "gyro_scale": "a gyro scale factor per axis",
    "structural_mode": "a flexible mode of the carrying frame between the body and a sensor",
    "compliant_body": "a sprung body on its suspension inside the frame (not rigid)",
}
# (effect, parameter) -> SI unit ("" dimensionless): io.export.EFFECT_UNITS, the one definition
UNITS = {(e, p): u for e, units in EFFECT_UNITS.items() for p, u in units.items()}
CHANNEL_UNITS = {"gyro": "rad/s", "accel": "m/s²", "torque": "N·m", "force": "N", "load_cell": "N"}

DIAGNOSIS_SCHEMA = "rig_identification.diagnosis_result"   # rig-identify diagnose --json, diagnosis.json
DIAGNOSIS_SCHEMA_VERSION = 1
_PER_CHANNEL = "per channel: gyro_* rad/s, accel_* m/s², torque_* N·m, force_* N, load_cell_* N"
DIAGNOSIS_UNITS = {
    "residual_rms_before": _PER_CHANNEL, "residual_rms_after": _PER_CHANNEL,
    "residual_rms_synchronous_before": _PER_CHANNEL, "residual_rms_synchronous_after": _PER_CHANNEL,
    "located.rms": _PER_CHANNEL, "located.mean": _PER_CHANNEL, "located.rms_by_tenth": _PER_CHANNEL,
    "located.peaks.hz": "Hz", "located.peaks.power_over_floor": "1: the peak's power over the local median",
    "inertia_about_cg_before": "kg·m², body axes, tensor entries (negated products)",
    "inertia_about_cg_after": "kg·m², body axes, tensor entries (negated products)",
    "inertia_std_before": "kg·m²", "inertia_std_after": "kg·m²", "band_hz": "Hz",
    "effects.evidence.likelihood_ratio": "1", "effects.evidence.p_value": "1",
    "effects.evidence.rms_reduction": "1: share of the channel's residual RMS removed",
    "candidates.likelihood_ratio": "1", "candidates.p_value": "1", "synchronous_revolutions": "1",
    "rigid_body_fit.inertia_about_cg": "kg·m², body axes, tensor entries (negated products)",
    "rigid_body_fit.inertia_std": "kg·m²", "rigid_body_fit.window.start": "s from the first IMU sample",
    "rigid_body_fit.window.end": "s from the first IMU sample", "rigid_body_fit.band_hz": "Hz",
}
FITS = {
    "rigid_body_fit": "the rigid-body fit and its verdict, the same as the command in its 'as' (the tensor "
                      "rig-identify inertia reports when it does not diagnose)",
    "inertia_about_cg_before": "diagnose's own rigid-body baseline, on its residual groups (gyro, accelerometer, "
                               "mean levels) against which its likelihood ratios are computed; not a result to quote",
    "inertia_about_cg_after": "diagnose's joint fit of the tensor and the effects found; rig-identify inertia adds "
                              "the effects to the model, fits again and validates: its tensor is the one to use",
}


def diagnosis_json(d: dict) -> dict:
    """Diagnose's JSON (:meth:`~rig_identification.diagnosis.result.Diagnosis.to_dict`, with
    ``rigid_body_fit`` when the command line adds it) with its schema, version, the unit of
    every numeric field (``units``; ``effects.parameters``: {effect: {parameter: unit}} of the
    effects and candidates present) and what each of its tensors is (``fits``)."""
    names = {e["name"] for e in d.get("effects") or []} | {c["name"] for c in d.get("candidates") or []}
    effect_units = {n: {p: u for (e, p), u in UNITS.items() if e == n} for n in sorted(names)}
    fits = {k: v for k, v in FITS.items() if k in d}
    return {"schema": DIAGNOSIS_SCHEMA, "schema_version": DIAGNOSIS_SCHEMA_VERSION,
            "units": {**DIAGNOSIS_UNITS, "effects.parameters": effect_units}, "fits": fits, **d}


def channel_unit(channel: str) -> str:
    """SI unit of a diagnosis channel (gyro_x, accel_y, torque_z, force_x, load_cell_c0, …)."""
    return next((u for p, u in CHANNEL_UNITS.items() if channel.startswith(p)), "")


def plus_minus(v, s) -> str:
    """``v ± s`` with ``s`` to two significant digits and ``v`` to the same decimals; lists
    element-wise; text as it is; a missing or non-finite σ left out."""
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        ss = list(s) if isinstance(s, (list, tuple, np.ndarray)) and len(s) == len(v) else [None] * len(v)
        return "[" + ", ".join(plus_minus(a, b) for a, b in zip(v, ss)) + "]"
    if not finite(v):
        return MISSING
    if not finite(s) or float(s) <= 0:
        return num(v, ".4g")
    d = max(0, 1 - int(math.floor(math.log10(float(s)))))
    return f"{num(v, f'.{d}f')} ± {num(s, f'.{d}f')}"


def parameters_text(e: dict) -> str:
    """An effect's parameters in words with σ and SI units, e.g. "angular = 300.5 ± 1.5
    N·m·s/rad, linear = 145.0 ± 3.5 N·s/m"."""
    std = e.get("parameters_std") or {}
    parts = []
    for k, v in (e.get("parameters") or {}).items():
        unit = UNITS.get((e.get("name"), k), "")
        parts.append(f"{k} = {plus_minus(v, std.get(k))}" + (f" {unit}" if unit else ""))
    return ", ".join(parts) if parts else "no parameters"


def effects_text(d: dict) -> str:
    """The named effects in one phrase, e.g. "viscous damping (angular = …, linear = …)"."""
    return "; ".join(f"{effect_name(e).replace('_', ' ')} ({parameters_text(e)})" for e in d.get("effects", []))


def evidence_text(e: dict) -> str:
    """The likelihood-ratio evidence of an effect as text."""
    ev = e.get("evidence") or {}
    lr, p = ev.get("likelihood_ratio"), ev.get("p_value")
    out = f"likelihood ratio {num(lr, '.1f')}" + (f" ({ev['dof']} dof)" if "dof" in ev else "")
    if finite(p):
        out += ", p < 1e-300" if p < 1e-300 else f", p = {p:.2g}"
    return out


def effects_table(effects: list[dict], ident: str) -> str:
    """Effects (named or hypotheses) as a table: name, what it is, parameters, evidence,
    plausibility."""
    rows = [[effect_name(e), Cell(EFFECT_TEXT.get(e["name"], ""), "text"), Cell(parameters_text(e), "text"),
             Cell(evidence_text(e), "text"),
             Cell("plausible" if e.get("plausible", True) else f"not plausible: {e.get('implausible', '')}",
                  "text")] for e in effects]
    return table(["effect", "what it is", "parameters (± σ, SI)", "evidence", "physically"], rows, ident=ident,
                 text_cols=range(5))


def rigid_body_table(result: InertiaResult) -> str:
    """The rigid-body fit (model_error) beside the reported fit with the effects, moments and
    products of inertia about the CG (vehicle-dynamics sign), kg·m²."""
    rb = result.rigid_body or {}
    val, std = rb.get("inertia_about_cg") or {}, rb.get("inertia_std") or {}
    theta = SIGN * from_tensor(result.inertia)
    rows = []
    for i in ORDER:
        k = KEYS[i]
        r = SIGN[i] * val[k] if finite(val.get(k)) else None
        rows.append([SYMBOL[k], num(r, ".2f"), num(std.get(k), ".3g"), num(theta[i], ".2f"),
                     num(result.inertia_std[i], ".3g"), num(None if r is None else theta[i] - r, "+.3g")])
    return table(["quantity", "rigid-body fit kg·m²", "σ kg·m² (widened)", "with the effects kg·m²", "σ kg·m²",
                  "difference kg·m²"], rows, ident="rigid-body-table")


def size_text(u: dict) -> str:
    """The size of an ``unexplained`` entry: a line's power over the residual's in-band median,
    or a coloured residual's RMS in the channel's unit."""
    if u.get("band_hz"):
        return f"{num(u.get('size'), '.3g')}× the in-band median power"
    return f"RMS {num(u.get('size'), '.3g')} {channel_unit(u['channel'])}".rstrip()


def unexplained_table(where: list[dict]) -> str:
    """Where the mismatch is: channel, band, time from the window's start, size, what the
    frequency is."""
    rows = [[u["channel"], f"{num(u['band_hz'][0], '.2f')}–{num(u['band_hz'][1], '.2f')}" if u.get("band_hz")
             else "the whole fit band",
             f"{num(u['time_s'][0], '.1f')}–{num(u['time_s'][1], '.1f')}" if u.get("time_s") else MISSING,
             size_text(u), Cell(u.get("is", ""), "text")] for u in where]
    return table(["channel", "band Hz", "time s (from the window start)", "size", "what the frequency is"], rows,
                 ident="unexplained-table", text_cols=(4,))


def diagnosis_html(result: InertiaResult) -> tuple[str, dict | None]:
    """The model-error section (HTML) and its numbers for report.json (None when the result
    was not diagnosed)."""
    d = result.diagnosis
    if d is None:
        return "", None
    handled = str(d.get("handled", ""))
    if d.get("effects") and not handled.startswith("not"):
        html = ("<h2>Model error: what diagnosis found</h2>"
                '<div class="finding"><p>The rigid-body fit failed its validation (model error). '
                "<code>rig-identify diagnose</code> named the effects below; they were "
                f"{esc(handled)}, the recording identified again, and that fit passed its validation: it is the "
                "fit this page reports (its tensor, σ and plots).</p>"
                + effects_table(d["effects"], "effects-table") + "</div>"
                "<h3>The rigid-body fit beside the reported fit</h3>" + rigid_body_table(result)
                + '<p class="note">Moments and products of inertia about the CG (vehicle-dynamics sign). The '
                "rigid-body fit's σ were widened by its model_error verdict.</p>")
        data = {"found": True, "handled": handled,
                "effects": [{"name": e["name"], "text": parameters_text(e)} for e in d["effects"]]}
        return html, data
    why = handled.removeprefix("not: ") or "no effect of diagnose's library explains the misfit"
    where = d.get("unexplained") or []
    hyp = d.get("hypotheses") or []
    html = ("<h2>Model error: not explained</h2>"
            f"<p>Diagnosis named nothing: {esc(why)}. The tensor is the rigid-body fit's (σ widened, not "
            "trustworthy).</p><h3>Where the mismatch is</h3>"
            + (unexplained_table(where) + '<p class="note">Spectral lines of each channel\'s rigid-body residual '
               "(size: power over the residual's median level in the fit band), or a residual that is not white "
               "(size: its RMS); time: the tenth of the window where the residual is largest when it stands out, "
               "else the whole window.</p>" if where else "<p>No line or coloured residual stands out in any "
               "channel.</p>")
            + '<div class="hypothesis"><h3>Hypotheses — not findings</h3>'
            + ("<p>diagnose's best candidates. None is adopted: with them the fit still fails its validation, or "
               "their parameters are not physically plausible. They are leads for the next test, not "
               "corrections of this one.</p>" + effects_table(hyp, "hypotheses-table") if hyp else
               "<p>diagnose had no candidate that reduces the misfit significantly.</p>")
            + "".join(f"<p><strong>Advice ({esc(e['name'])}):</strong> {esc(e['advice'])}</p>"
                      for e in hyp if e.get("advice")) + "</div>")
    data = {"found": False, "why": why, "unexplained": where,
            "hypotheses": [{"name": e["name"], "text": parameters_text(e)} for e in hyp],
            "advice": [e["advice"] for e in hyp if e.get("advice")]}
    return html, data


__all__ = ["diagnosis_html", "diagnosis_json", "effects_text", "parameters_text", "plus_minus", "channel_unit",
           "EFFECT_TEXT", "UNITS", "DIAGNOSIS_SCHEMA", "DIAGNOSIS_UNITS"]
