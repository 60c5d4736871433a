"""The predicted σ of the identified tensor as data: :class:`Prediction` for one planned run (or
several fitted jointly, :func:`combine`), and its most weakly determined combination in a lab
engineer's words (:func:`describe_weak`).

Computed by :func:`~rig_identification.estimation.propagation.predict_from_trajectory`; the experiment
design (:mod:`rig_identification.design.planning`) and the pipeline's σ read it.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..io.verdict import KEYS
from ..model.parametrisation import entry_scales, from_tensor
from .directions import describe_direction, weak_directions


class PlanError(ValueError):
    """The planned experiment cannot be predicted or designed (no motion, bad limits)."""


@dataclass
class Prediction:
    """Predicted first-order uncertainty of the identified tensor for one run (or several
    fitted jointly).

    inertia: (3,3) nominal tensor, kg·m²; std: (6,) predicted σ in :data:`KEYS` order,
    kg·m²; covariance (6,6); gyro_white_std (6,): the white-gyro-only bound (what the
    identifier reports as ``crb_std``); contributions: {source: (6,) σ of that noise source
    alone}; weights (3,) the identifier's per-gyro-axis weights 1/σ², (rad/s)⁻²;
    residual_rms (3,) rad/s predicted residual of the band-passed fit; band_hz; duration s
    (fitted windows, summed); n_samples; runs; rotation_rms (3,) rad/s band-passed body rate
    per body axis.  axis_bread (3,6,6), axis_meats {source: (3,3,6,6)}, white_bread and
    white_meat (6,6) keep the per-axis pieces of the sandwich so that runs can be combined
    (:func:`combine`) with pooled weights: bread = Σ_a w_a B_a, meat = Σ_ab w_a w_b M_ab.
    gyro_sensitivity (K,3,6), only when asked for (:func:`predict_from_trajectory`): the
    linearised estimate error per gyro noise sample, ``δj ≈ Σ_n,d S[n,d] ν[n,d]`` for gyro
    noise ν (K,3) rad/s in IMU axes at the trajectory's samples — lets a Monte Carlo
    evaluate the first-order model on its own noise draws (a control variate).
    """

    inertia: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    gyro_white_std: np.ndarray
    contributions: dict[str, np.ndarray]
    weights: np.ndarray
    residual_rms: np.ndarray
    band_hz: tuple[float, ...]
    duration: float
    n_samples: int
    rotation_rms: np.ndarray
    axis_bread: np.ndarray
    axis_meats: dict[str, np.ndarray]
    white_bread: np.ndarray
    white_meat: np.ndarray
    runs: int = 1
    gyro_sensitivity: np.ndarray | None = None

    @staticmethod
    def assemble(inertia: np.ndarray, axis_bread: np.ndarray, axis_meats: dict[str, np.ndarray],
                 white_bread: np.ndarray, white_meat: np.ndarray, residual_var: np.ndarray, band_hz: Sequence[float],
                 duration: float, n_samples: int, rotation_rms: np.ndarray, runs: int = 1) -> "Prediction":
        """Sandwich covariance from the per-axis pieces with weights 1/residual_var."""
        w = 1.0 / np.asarray(residual_var, float)
        bread = np.einsum("a,aij->ij", w, axis_bread)
        Bi = np.linalg.inv(bread)
        meats = {s: np.einsum("a,b,abij->ij", w, w, M) for s, M in axis_meats.items()}
        cov = Bi @ sum(meats.values()) @ Bi.T
        contrib = {s: np.sqrt(np.clip(np.diag(Bi @ M @ Bi.T), 0, None)) for s, M in meats.items()}
        Bu = np.linalg.inv(white_bread)
        gws = np.sqrt(np.clip(np.diag(Bu @ white_meat @ Bu), 0, None))
        return Prediction(np.asarray(inertia, float), np.sqrt(np.clip(np.diag(cov), 0, None)), cov, gws, contrib,
                          w, np.sqrt(residual_var), tuple(band_hz), float(duration), int(n_samples),
                          np.asarray(rotation_rms, float), axis_bread, axis_meats, white_bread, white_meat, runs)

    @property
    def scale(self) -> np.ndarray:
        """(6,) reference of each entry: diagonals themselves, products the largest diagonal."""
        return entry_scales(from_tensor(self.inertia))

    @property
    def relative_std(self) -> np.ndarray:
        """(6,) σ / scale (dimensionless)."""
        rel: np.ndarray = self.std / self.scale
        return rel

    @property
    def objective(self) -> float:
        """The largest relative σ over the six entries."""
        return float(np.max(self.relative_std))

    def worst(self, ref: np.ndarray | None = None) -> float:
        """max_k σ_k / ref_k (ref: (6,) per-entry reference, default :attr:`scale`)."""
        return float(np.max(self.std / (self.scale if ref is None else ref)))

    def scaled(self, factor: float) -> "Prediction":
        """The same run lasting ``factor`` times as long (information × factor, σ / sqrt(factor))."""
        return Prediction.assemble(self.inertia, self.axis_bread * factor,
                                   {s: M * factor for s, M in self.axis_meats.items()}, self.white_bread * factor,
                                   self.white_meat * factor, self.residual_rms**2, self.band_hz,
                                   self.duration * factor, int(self.n_samples * factor), self.rotation_rms, self.runs)

    def weak(self, n: int = 2) -> list[dict[str, Any]]:
        """The ``n`` most weakly determined combinations, in the words of the CLI, the JSON and the
        report (:func:`~rig_identification.estimation.directions.describe_direction`, with how
        much the body turned about the axis each needs)."""
        scale = float(np.trace(self.inertia)) / 3
        return [describe_direction(rel, D, scale=scale, weakest=i == 0, rotation_rms=self.rotation_rms)
                for i, (rel, D) in enumerate(weak_directions(self.inertia, self.covariance, n))]

    def to_dict(self) -> dict[str, Any]:
        return {"std": {k: float(v) for k, v in zip(KEYS, self.std)},
                "relative_std": {k: float(v) for k, v in zip(KEYS, self.relative_std)},
                "gyro_white_std": {k: float(v) for k, v in zip(KEYS, self.gyro_white_std)},
                "contributions": {s: {k: float(v) for k, v in zip(KEYS, c)} for s, c in self.contributions.items()},
                "max_relative_std": self.objective,
                "residual_rms_rad_s": [float(x) for x in self.residual_rms],
                "rotation_rms_rad_s": [float(x) for x in self.rotation_rms],
                "band_hz": [float(self.band_hz[0]), float(self.band_hz[1])],
                "duration_s": float(self.duration), "runs": int(self.runs),
                "weakly_determined": self.weak()}


def combine(preds: list[Prediction]) -> Prediction:
    """Joint prediction of independent runs fitted together with one tensor (the joint fit
    of :func:`~rig_identification.estimation.identification.identify_inertia_joint`): information (AᵀWA) and noise
    (meat) add over the runs, with the per-axis weights pooled over the runs (one gyro).
    Raises :class:`PlanError` for an empty list."""
    if not preds:
        raise PlanError("no runs to combine")
    if len(preds) == 1:
        return preds[0]
    n = np.array([p.n_samples for p in preds], float)
    var = sum(ni * p.residual_rms**2 for ni, p in zip(n, preds)) / n.sum()
    meats = {s: sum(p.axis_meats[s] for p in preds if s in p.axis_meats)
             for s in dict.fromkeys(k for p in preds for k in p.axis_meats)}
    rot = np.sqrt(sum(ni * p.rotation_rms**2 for ni, p in zip(n, preds)) / n.sum())
    # the ignores: typeshed's sum() adds "| Literal[0]" (an empty iterable); preds is not empty here
    return Prediction.assemble(preds[0].inertia, sum(p.axis_bread for p in preds), meats,  # type: ignore[arg-type]
                               sum(p.white_bread for p in preds),  # type: ignore[arg-type]
                               sum(p.white_meat for p in preds), var,  # type: ignore[arg-type]
                               (min(p.band_hz[0] for p in preds), max(p.band_hz[1] for p in preds)),
                               sum(p.duration for p in preds), int(n.sum()), rot, sum(p.runs for p in preds))


