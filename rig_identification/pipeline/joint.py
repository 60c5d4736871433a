"""Several recordings of one body read at once (``rig-identify inertia RUN1 RUN2 …``): each
prepared and fitted alone as one recording is (:mod:`~rig_identification.pipeline.rig_model`, no
diagnosis), then all at once, each run's own rig model, the body's mass, CG and tensor shared
(:func:`fit_recordings`, :func:`~rig_identification.estimation.joint_fit.fit_jointly`) →
:class:`JointResult`.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from ..estimation.joint_fit import fit_jointly
from ..estimation.rig_problem import sequential_blas
from ..io.export import Axes, Expressed, express
from ..io.recording import Recording, RecordingError
from ..io.rig import Rig
from ..io.verdict import KEYS
from ..model.parametrisation import to_tensor
from .rig_model import RigModelResult, prepared

log = logging.getLogger(__name__)

MASS_RTOL = 1e-3   # relative: rig.yaml body.mass of recordings fitted jointly must agree this well
CG_TOL = 0.002     # m: and their body.center_of_gravity this well


class RigSource(Protocol):
    """What :func:`check_same_body` reads of a recording: its rig and its folder (None for an
    in-memory one)."""

    @property
    def rig(self) -> Rig: ...

    @property
    def path(self) -> Path | None: ...


def _rig_file(rec: RigSource) -> str:
    """The recording's rig.yaml, or its rig's source for an in-memory recording."""
    return str(Path(rec.path) / "rig.yaml") if rec.path is not None else str(rec.rig.source)


def check_same_body(recs: Sequence[RigSource], mass_rtol: float = MASS_RTOL, cg_tol: float = CG_TOL) -> None:
    """Refuse a joint fit of recordings whose rig.yaml describe different bodies: body.mass
    must agree within ``mass_rtol`` (relative) and body.center_of_gravity within ``cg_tol``
    m (body axes) of the first recording's.  Raises
    :class:`~rig_identification.io.recording.RecordingError` naming both files."""
    ref = recs[0]
    m0, c0 = ref.rig.mass, ref.rig.require_cg()
    for r in recs[1:]:
        m, c = r.rig.mass, r.rig.require_cg()
        where = f"{_rig_file(ref)} and {_rig_file(r)}"
        if abs(m - m0) > mass_rtol * abs(m0):
            raise RecordingError(f"{where} describe different bodies: body.mass {m0:g} kg vs {m:g} kg (a joint "
                                 f"fit needs the same body; tolerance {100 * mass_rtol:g} %)")
        d = float(np.linalg.norm(np.asarray(c) - np.asarray(c0)))
        if d > cg_tol:
            raise RecordingError(f"{where} describe different bodies: body.center_of_gravity "
                                 f"[{', '.join(f'{x:g}' for x in c0)}] vs [{', '.join(f'{x:g}' for x in c)}] m, "
                                 f"{1000 * d:.1f} mm apart (a joint fit needs the same body; tolerance "
                                 f"{1000 * cg_tol:g} mm)")


#: The verdicts from the worst to the best: a joint fit's is its worst record's.
SEVERITY = ("failed", "model_error", "not_identifiable", "inconsistent", "ok")


@dataclass(frozen=True)
class JointResult:
    """The rig model fitted to several recordings of one body (:func:`fit_recordings`).

    results: each recording's :class:`RigModelResult` at the joint estimate (the body — mass, CG,
    tensor, σ, CRB, minima — the same in each; its own cables, geometry, channels and levels).
    alone: each recording fitted by itself (what each run alone determines).  seconds: wall time.
    """

    results: tuple[RigModelResult, ...]
    alone: tuple[RigModelResult, ...]
    seconds: float

    @property
    def first(self) -> RigModelResult:
        """The first recording's result: the body's estimate, σ and verdict lines are every one's."""
        return self.results[0]

    @property
    def cg_source(self) -> str:
        """Where the CG's prior came from (every recording's: one is given for all)."""
        return self.first.cg_source

    @property
    def verdict(self) -> str:
        """The worst of the recordings' verdicts (:data:`SEVERITY`): every channel of every
        recording must fit, and the joint tensor be determined."""
        return min((r.verdict for r in self.results), key=SEVERITY.index)

    @property
    def summary(self) -> str:
        """The verdict and what it means, one line; a channel that does not fit named with its recording."""
        worst = next(r for r in self.results if r.verdict == self.verdict)
        line = worst.verdict_line
        return f"{line} (in {worst.path})" if self.verdict in ("model_error", "failed") else line

    @property
    def withheld(self) -> tuple[str, ...]:
        return KEYS if self.verdict in ("not_identifiable", "failed") else ()

    def expressed(self, axes: str | Axes = "body") -> Expressed:
        """The body's mass, CG and tensor in ``axes`` with σ, the :attr:`withheld` entries left out."""
        f = self.first.fit
        return express(f.body.mass, f.body.cg, to_tensor(f.inertia), f.inertia_std, self.withheld, axes)

    def to_dict(self) -> dict:
        """The JSON object of ``rig-identify inertia REC1 REC2 … --json``: the body as one recording's
        result gives it (verdict, tensor, σ, CRB, mass, CG, minima, truth), then ``recordings``: each
        one's own part (window, cables, damping, channels, offsets, warnings) and what it determines alone."""
        d = self.first.to_dict()
        own = ("recording", "window", "cables", "body_damping", "residual_level", "offsets", "poorly_fitted_channels",
               "natural_frequencies_hz", "warnings", "extensions", "diagnosis", "rigid_body_fit", "inertia_start",
               "survey")
        for k in own:
            d.pop(k, None)
        d.update(schema="rig_identification.joint_rig_model_result", schema_version=2,
                 model="rig (grey-box, every sensor an output), one body over several recordings",
                 verdict=self.verdict, summary=self.summary, seconds=self.seconds)
        d["recordings"] = []
        for r, a in zip(self.results, self.alone):
            one = r.to_dict()
            part = {k: one[k] for k in own if k in one}
            part["verdict"] = r.verdict
            part["alone"] = {"verdict": a.verdict, "undetermined": a.undetermined, "ambiguous": a.ambiguous,
                             "inertia_about_cg": {k: float(v) for k, v in zip(KEYS, a.fit.inertia)},
                             "inertia_std": {k: float(v) for k, v in zip(KEYS, a.fit.inertia_std)}}
            d["recordings"].append(part)
        return d


def fit_recordings(recs: list[Recording], cg=None, cg_std=None, cg_source: str | None = None,
                   start: float | None = None, end: float | None = None) -> JointResult:
    """Fit the rig model to several recordings of one body at once
    (:func:`~rig_identification.estimation.joint_fit.fit_jointly`: each run's cables, load cells,
    geometry and states its own, the body's mass, CG and tensor shared).  The bodies must agree
    (:func:`check_same_body`, before any fit).  Each recording is prepared and fitted alone first
    (:func:`~rig_identification.pipeline.rig_model.prepared`, the rigid-body rig model: no
    diagnosis; run ``rig-identify diagnose`` on a recording whose channels do not fit).  cg,
    cg_std, cg_source, start, end: as :func:`~rig_identification.pipeline.rig_model.fit_whole_recording`'s,
    the same for every recording.  Raises as it does."""
    with sequential_blas():
        check_same_body(recs)
        t_wall = time.perf_counter()
        inputs = [prepared(r, cg, cg_std, cg_source, start, end) for r in recs]
        singles = []
        for inp in inputs:
            log.info("fitting the rig model to %s alone (%.0f s)", inp.rec.path, inp.rc.duration)
            singles.append(inp.fit())
        alone = tuple(inp.result(f, np.nan) for inp, f in zip(inputs, singles))
        log.info("fitting the rig model to the %d recordings at once", len(recs))
        joint = fit_jointly([i.rc for i in inputs], singles, [i.prior for i in inputs])
        seconds = time.perf_counter() - t_wall
        return JointResult(tuple(inp.result(f, seconds) for inp, f in zip(inputs, joint.fits)), alone, seconds)
