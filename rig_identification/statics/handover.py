"""The centre of gravity handed on to the dynamic experiment: a saved CG result read back, and
rig.yaml written with the CG.

:func:`load_cg_result` reads the JSON of ``rig-identify cg --json`` (schema
:data:`~.result.CG_RESULT_SCHEMA`, e.g. for ``rig-identify inertia --cg CG.json``);
:func:`cg_result_from_dict` the same object from memory (the identifier node's
``~/estimate_cg`` answer).  :func:`rig_with_cg_text` is the rig.yaml of ``--write-rig``
(``rig-identify cg`` and ``mass_properties_client cg-estimate``), :func:`check_rig_target`
the checks on its target.  Errors: :class:`CgResultError` (a
:class:`~.state.StaticsError`) naming the file and the field.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.rig import Rig, dump_rig, read_text
from .result import CG_RESULT_SCHEMA, CG_RESULT_SCHEMA_VERSION, CgResult
from .state import StaticsError


class CgResultError(StaticsError):
    """A CG result file (the JSON of ``rig-identify cg --json``) or a ``--write-rig`` target
    that cannot be used; the message names the file and the field."""


@dataclass(frozen=True)
class SavedCgResult:
    """A CG result read from a file (:func:`load_cg_result`).

    center_of_gravity (3,) body frame m; center_of_gravity_std (3,) m (measurement noise and
    geometry); center_of_gravity_std_noise (3,) m or None (files before schema version 1);
    covariance (3, 3) m² or None; mass kg or None; verdict: the validation's (``ok``,
    ``model_error``) or None; schema_version (0: a file without ``schema``, written before
    the field existed); source: the file; geometry_std: the geometry's σ the estimate assumed
    (``uncertainty.geometry_std``: anchors, cable_lengths, dummy_position, m; empty when the
    file has none); failed: the names of the validation's failed checks."""

    center_of_gravity: np.ndarray
    center_of_gravity_std: np.ndarray
    center_of_gravity_std_noise: np.ndarray | None
    covariance: np.ndarray | None
    mass: float | None
    verdict: str | None
    schema_version: int
    source: str
    geometry_std: dict = field(default_factory=dict)
    failed: tuple[str, ...] = ()


def _vec3(d: dict, key: str, src: str, positive: bool = False) -> np.ndarray:
    v = d.get(key)
    if v is None:
        raise CgResultError(f"{src}: missing field {key}")
    if not isinstance(v, list) or len(v) != 3 or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                          for x in v):
        raise CgResultError(f"{src}: field {key} must be a list of 3 numbers, got {v!r}")
    a = np.array(v, float)
    for i, x in enumerate(a):
        if not math.isfinite(x):
            raise CgResultError(f"{src}: field {key}[{i}] must be finite, got {v[i]!r}")
        if positive and x <= 0:
            raise CgResultError(f"{src}: field {key}[{i}] must be > 0, got {v[i]!r}")
    return a


def _optional_vec3(d: dict, key: str, src: str, positive: bool = False) -> np.ndarray | None:
    """:func:`_vec3`, or None when the field is missing."""
    return None if d.get(key) is None else _vec3(d, key, src, positive)


def load_cg_result(path: str | Path) -> SavedCgResult:
    """Read a CG result file: the JSON object ``rig-identify cg --json`` prints (schema
    :data:`~.result.CG_RESULT_SCHEMA`, versions up to :data:`~.result.CG_RESULT_SCHEMA_VERSION`;
    a file without ``schema``, from before it existed, is read as version 0), e.g. for
    ``rig-identify inertia --cg CG.json``.

    Returns :class:`SavedCgResult` (CG (3,) body frame m and its σ).  Raises
    :class:`CgResultError` naming the file and the field: unreadable, not JSON, another
    schema or a newer version, frame not ``body``, CG or σ not 3 finite numbers (σ > 0),
    a covariance that is not (3, 3) finite and symmetric."""
    src = str(path)
    text = read_text(path, CgResultError, "CG result")
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise CgResultError(f"{src}: not JSON ({e.msg} at line {e.lineno}, column {e.colno}); save the output of "
                            "rig-identify cg --json") from None
    return cg_result_from_dict(d, src)


def cg_result_from_dict(d, src: str) -> SavedCgResult:
    """:class:`SavedCgResult` of a CG result's JSON object ``d`` (as :func:`load_cg_result`
    reads it from a file; also the identifier node's ~/estimate_cg answer); ``src`` names it
    in errors.  Raises :class:`CgResultError` as :func:`load_cg_result`."""
    if not isinstance(d, dict):
        raise CgResultError(f"{src}: a CG result is a JSON object, got {type(d).__name__}")
    schema = d.get("schema")
    if schema is None:
        version = 0
    elif schema != CG_RESULT_SCHEMA:
        raise CgResultError(f"{src}: field schema is {schema!r}, not {CG_RESULT_SCHEMA!r} "
                            "(not a rig-identify cg result)")
    else:
        declared = d.get("schema_version")
        if not isinstance(declared, int) or isinstance(declared, bool) or declared < 1:
            raise CgResultError(f"{src}: field schema_version must be an integer >= 1, got {declared!r}")
        version = declared
        if version > CG_RESULT_SCHEMA_VERSION:
            raise CgResultError(f"{src}: field schema_version is {version}, written by a newer rig_identification; "
                                f"this one reads up to {CG_RESULT_SCHEMA_VERSION}")
    frame = d.get("frame", "body")
    if frame != "body":
        raise CgResultError(f"{src}: field frame is {frame!r}; the CG must be in the body frame")
    c = _vec3(d, "center_of_gravity", src)
    sd = _vec3(d, "center_of_gravity_std", src, positive=True)
    sdn = _optional_vec3(d, "center_of_gravity_std_noise", src, positive=True)
    cov = None
    raw = d.get("center_of_gravity_covariance")
    if raw is not None:
        try:
            cov = np.array(raw, float)
        except (TypeError, ValueError):
            cov = None
        if cov is None or cov.shape != (3, 3) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T, rtol=1e-9,
                                                                                                   atol=0.0):
            raise CgResultError(f"{src}: field center_of_gravity_covariance must be a symmetric 3×3 list of "
                                "finite numbers")
    mass = d.get("mass")
    if mass is not None and (isinstance(mass, bool) or not isinstance(mass, (int, float)) or not math.isfinite(mass)
                             or mass <= 0):
        raise CgResultError(f"{src}: field mass must be a number > 0, got {mass!r}")
    val = d.get("validation")
    verdict = val.get("verdict") if isinstance(val, dict) else None
    failed = tuple(str(x) for x in val.get("failed") or ()) if isinstance(val, dict) else ()
    unc = d.get("uncertainty")
    geo = unc.get("geometry_std") if isinstance(unc, dict) else None
    geo = {str(k): float(v) for k, v in geo.items() if isinstance(v, (int, float)) and not isinstance(v, bool)} \
        if isinstance(geo, dict) else {}
    return SavedCgResult(c, sd, sdn, cov, None if mass is None else float(mass), verdict, int(version), src, geo,
                         failed)


def check_rig_target(out: Path, force: bool, recordings: list[Path]) -> None:
    """Refuse a --write-rig target that exists (unless ``force``) or is a recording's own rig.yaml."""
    for rec in recordings:
        own = rec / "rig.yaml"
        if own.exists() and out.exists() and out.resolve() == own.resolve():
            raise CgResultError(f"{out}: --write-rig would replace the recording {rec}'s own rig.yaml; a recording "
                                "stays as it was recorded: write the copy elsewhere")
    if out.is_dir():
        raise CgResultError(f"{out}: --write-rig names a folder; give the file to write (e.g. {out / 'rig.yaml'})")
    if out.exists() and not force:
        raise CgResultError(f"{out}: already exists; refusing to overwrite it (pass --force to replace it)")


def rig_with_cg_text(rig: Rig, result: "CgResult | SavedCgResult", sources: list[str], created: str,
                     original: str | None = None, by: str = "rig-identify cg") -> str:
    """rig.yaml text: ``rig`` with ``body.center_of_gravity`` set to ``result``'s estimate (a
    :class:`~.result.CgResult`, or the :class:`SavedCgResult` of its JSON: what
    ``mass_properties_client cg-estimate`` receives from the identifier node), headed by
    comment lines (``created``, ``by`` what, the σ with and without the geometry, the validation
    verdict, the ``sources``: the static recordings, or what captured the states) and the
    leading comment lines of ``original`` (the source rig.yaml's text, if given).  The values
    are written exactly (YAML floats round-trip); rig.yaml's other fields are kept
    (:func:`~rig_identification.io.rig.dump_rig`)."""
    c, sd = result.center_of_gravity, result.center_of_gravity_std
    mm = ", ".join(f"{x * 1e3:.2f}" for x in sd)
    noise = result.center_of_gravity_std_noise
    geo = result.geometry_std
    if isinstance(result, SavedCgResult):
        verdict, failed = result.verdict, result.failed
    else:
        verdict, failed = (None, ()) if result.validation is None else (result.validation.verdict,
                                                                          result.validation.failed)
    cg_text = ", ".join(f"{x:.5f}" for x in c)
    lines = [f"body.center_of_gravity = [{cg_text}] m estimated by {by} on {created}",
             f"σ {mm} mm (x, y, z: measurement noise and geometry, anchors {geo.get('anchors', 0) * 1e3:g} mm, "
             f"cable lengths {geo.get('cable_lengths', 0) * 1e3:g} mm, dummy position "
             f"{geo.get('dummy_position', 0) * 1e3:g} mm)"
             + ("" if noise is None else "; noise only " + ", ".join(f"{x * 1e3:.2f}" for x in noise) + " mm"),
             "validation: " + ("not run" if verdict is None else verdict
                               + (f" ({', '.join(failed)} failed)" if failed else "")),
             "from " + " and ".join(sources)]
    head = "".join(f"# {x}\n" for x in lines)
    if original:
        lead = []
        for line in original.splitlines():
            if not line.startswith("#"):
                break
            lead.append(line + "\n")
        head += "".join(lead)
    return head + dump_rig(rig.with_cg(c))
