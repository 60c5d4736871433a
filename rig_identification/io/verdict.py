"""The verdict on an inertia fit, as data: :class:`Check` and :class:`Validation`.

The checks themselves are in :mod:`rig_identification.estimation.validation`; this module holds the result types so
that the identifier's result (:class:`~rig_identification.estimation.inertia_result.InertiaResult`) can carry them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
VERDICTS = ("ok", "model_error", "not_identifiable")
NAMES = {"ixx": "moment Ixx", "iyy": "moment Iyy", "izz": "moment Izz",
         "ixy": "product Ixy", "ixz": "product Ixz", "iyz": "product Iyz"}
"""An entry in the verdict's words: by its body axes, never roll, pitch or yaw (the verdict does
not know where the vehicle lies: rig.yaml ``body.vehicle``)."""


def fmt_p(p: float) -> str:
    """A p-value as text: ``p < 1e-300`` for underflow."""
    return "< 1e-300" if p < 1e-300 else f"{p:.2g}"


@dataclass(frozen=True)
class Check:
    """One validation check: ``name``; ``statistic`` and ``threshold`` (``passed`` when the
    statistic is at most the threshold; None when the check does not apply); ``detail``:
    what it measured, in words; ``sigma_factor`` ≥ 1: a consistency check that found the
    data a little less consistent than the noise explains, but within its threshold, widens
    σ by this factor (the Birge ratio √(χ²/dof); 1 when it found nothing)."""

    name: str
    statistic: float | None
    threshold: float | None
    passed: bool | None
    detail: str
    sigma_factor: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        def num(x: float | None) -> float | None:
            return None if x is None or not np.isfinite(x) else float(x)
        return {"name": self.name, "statistic": num(self.statistic), "threshold": num(self.threshold),
                "passed": self.passed, "detail": self.detail, "sigma_factor": float(self.sigma_factor)}


@dataclass(frozen=True)
class Validation:
    """The verdict on a fit and its checks.

    verdict: one of :data:`VERDICTS`; checks: the :class:`Check` list; undetermined: the
    entries (:data:`~rig_identification.io.verdict.KEYS`) the recording does not determine; advice: what
    to change (rig, excitation), in words; segment_inertia (K,6) and band_inertia (2,6):
    the tensor entries fitted on each time segment and frequency sub-band (kg·m²), band_edges
    (3,) Hz; spread_std (6,) kg·m²: the spread the checks saw (segments and sub-bands), which
    widens σ whenever a consistency check failed; failed: the names of the failed checks; sigma_factor ≥ 1: the
    largest :attr:`Check.sigma_factor`, by which σ is widened whatever the verdict; model: the
    model the checks validated, in words ("the rigid-body model", or with the effects a
    diagnosis added: "the rigid-body model with viscous_damping")."""

    verdict: str
    checks: tuple[Check, ...]
    undetermined: tuple[str, ...] = ()
    advice: tuple[str, ...] = ()
    segment_inertia: np.ndarray | None = None
    segment_times: np.ndarray | None = None
    band_inertia: np.ndarray | None = None
    band_edges: tuple[float, ...] | None = None
    spread_std: np.ndarray | None = None
    failed: tuple[str, ...] = field(default=())
    sigma_factor: float = 1.0
    model: str = "the rigid-body model"

    @property
    def summary(self) -> str:
        """The verdict in words, first line of every output."""
        if self.verdict == "ok":
            return (f"verdict: ok — {self.model} explains the recording (every validation check passed); "
                    + ("the σ below are calibrated" if self.sigma_factor <= 1.0 else
                       f"the σ below are the noise's widened {self.sigma_factor:.2f}× for what the consistency "
                       "checks saw beyond the noise"))
        if self.verdict == "model_error":
            return (f"verdict: MODEL ERROR — the recording disagrees with {self.model} ("
                    + ", ".join(self.failed) + " failed): the tensor below is not trustworthy; its σ is widened "
                    "to the spread the checks saw and is a lower bound of the error")
        return ("verdict: NOT IDENTIFIABLE — the recording does not determine "
                + ", ".join(NAMES[k] for k in self.undetermined) + " (reported as null)"
                + ("; " + "; ".join(self.advice) if self.advice else ""))

    def to_dict(self, origins: list[float] | None = None) -> dict[str, Any]:
        """The validation as JSON (``"validation"`` of
        :meth:`~rig_identification.estimation.inertia_result.InertiaResult.to_dict`).  origins: one stamp (s) per time
        segment, the first IMU sample of its recording: each segment's ``start``/``end`` are
        then seconds from it (as the window's), the header stamps in ``start_stamp``/
        ``end_stamp``; None: ``start``/``end`` are the stamps too."""
        def rows(a: np.ndarray) -> list[dict[str, float]]:
            return [{k: float(v) for k, v in zip(KEYS, r)} for r in a]

        def segment(i: int, t0: float, t1: float, r: dict[str, float]) -> dict[str, Any]:
            o = 0.0 if origins is None else float(origins[i])
            return {"start": float(t0) - o, "end": float(t1) - o, "start_stamp": float(t0), "end_stamp": float(t1),
                    "inertia_about_cg": r}

        segments: list[dict[str, Any]] | None = None
        if self.segment_inertia is not None:
            assert self.segment_times is not None    # set together with segment_inertia
            segments = [segment(i, t0, t1, r) for i, ((t0, t1), r) in enumerate(zip(self.segment_times,
                                                                                   rows(self.segment_inertia)))]
        sub_bands: list[dict[str, Any]] | None = None
        if self.band_inertia is not None:
            assert self.band_edges is not None       # set together with band_inertia
            sub_bands = [{"band_hz": [float(self.band_edges[i]), float(self.band_edges[i + 1])], "inertia_about_cg": r}
                         for i, r in enumerate(rows(self.band_inertia))]
        return {"verdict": self.verdict, "model": self.model, "summary": self.summary,
                "checks": [c.to_dict() for c in self.checks],
                "undetermined": list(self.undetermined), "advice": list(self.advice),
                "segments": segments,
                "sub_bands": sub_bands,
                "spread_std": None if self.spread_std is None else
                {k: float(v) for k, v in zip(KEYS, self.spread_std)}, "sigma_factor": float(self.sigma_factor)}


