"""The identified mass properties as data: :class:`InertiaResult` (the tensor, its σ and
covariance, the fit's window and validation) with its JSON (:meth:`InertiaResult.to_dict`),
and :class:`FitSeries`, the fit's output over one segment.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..io.export import (
    BODY,
    INERTIA_SCHEMA,
    INERTIA_SCHEMA_VERSION,
    UNITS,
    Axes,
    Expressed,
    convention_lines,
    express,
    finite_or_none,
)
from ..io.verdict import KEYS, Validation
from ..model.parametrisation import entry_scales, from_tensor, physically_consistent
from .directions import describe_direction
from .precision import TARGET, Precision, precision_of


@dataclass
class FitSeries:
    """The fit's output over one segment (one recording's window): t (N,) s; measured
    (N,3) band-passed gyro, rad/s, body axes; predicted (N,3) the model's band-passed ω
    with the identified tensor; band_hz the pass band; label the segment's name."""

    t: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    band_hz: tuple[float, float]
    label: str = ""
    # the fit's local linearisation, for model validation (:mod:`rig_identification.estimation.validation`): jacobian
    # (N,3,6) d predicted / d tensor entries (KEYS order), rad/s per kg·m²; axis_scale (3,)
    # rad/s, the per-axis residual scale that weighted the fit; fs Hz
    jacobian: np.ndarray | None = None
    axis_scale: np.ndarray | None = None
    fs: float | None = None

    @property
    def residual(self) -> np.ndarray:
        """(N,3) rad/s measured − predicted."""
        r: np.ndarray = self.measured - self.predicted
        return r


@dataclass(frozen=True)
class InertiaResult:
    """Identified mass properties.

    mass kg; center_of_gravity (3,) body m; inertia (3,3) kg·m² about the CG, body axes
    (geometry_msgs/Inertia entries: off-diagonals are negated products of inertia);
    inertia_std (6,) in :data:`~rig_identification.io.verdict.KEYS` order; covariance (6,6); correlation (6,6);
    weak_directions: list of (relative std, (3,3) unit-norm tensor direction) for the
    poorly determined combinations; residual_rms (3,) rad/s of the band-passed gyro fit;
    series: one :class:`FitSeries` per fitted segment (empty for the thesis baseline).
    A joint fit (:func:`~rig_identification.estimation.identification.identify_inertia_joint`):
    t_start/t_end are the earliest start
    and latest end over the segments, n_samples their total, band_hz the union of bands.
    """

    mass: float
    center_of_gravity: np.ndarray
    inertia: np.ndarray
    inertia_std: np.ndarray
    covariance: np.ndarray
    t_start: float
    t_end: float
    n_samples: int
    band_hz: tuple[float, float]
    residual_rms: np.ndarray
    fit_r2: np.ndarray
    weak_directions: list[tuple[float, np.ndarray]] = field(default_factory=list)
    method: str = "prediction error (band-limited output error, integrated Newton–Euler)"
    warnings: list[str] = field(default_factory=list)
    crb_std: np.ndarray | None = None
    gyro_noise: float | None = None
    series: list[FitSeries] = field(default_factory=list)
    # filled by pipeline.identify_recording: the load cells' mean vertical force over
    # rig.yaml's weight, − 1 (pipeline.weight_surplus)
    weight_surplus: float | None = None
    uncertainty: str = "sandwich"   # what inertia_std is: the sandwich, widened where the validation says
    # filled by pipeline.identify_recording(s): the model validation's verdict and checks
    # (validation.validate)
    validation: Validation | None = None
    # the lab's precision target (a fraction: 0.01 is ±1 % at 95 %), which :attr:`precision` judges
    precision_target: float = TARGET
    # filled by pipeline.with_cg_uncertainty: the σ (6,) kg·m² that the CG's own σ adds to the
    # tensor's (already in inertia_std and covariance); None when the CG was taken as exact
    cg_contribution_std: np.ndarray | None = None

    @property
    def correlation(self) -> np.ndarray:
        """(6,6) correlation of the entries (NaN where a σ is 0 or not finite)."""
        with np.errstate(all="ignore"):
            s = np.sqrt(np.clip(np.diag(self.covariance), 0, None))
            return self.covariance / np.outer(s, s)

    def expressed(self, axes: str | Axes = "body") -> Expressed:
        """The mass properties in ``axes`` (:func:`~rig_identification.io.export.axes_for`, which knows the
        vehicle's orientation, or a name: ``body``, rig.yaml's), the undetermined entries left out: an
        :class:`~rig_identification.io.export.Expressed` (:func:`~rig_identification.io.export.express`, the one
        way to other axes).  Raises :class:`~rig_identification.io.vehicle.AxesError` for vehicle axes asked by
        name (the result does not know the vehicle) and for an unknown name."""
        return express(self.mass, self.center_of_gravity, self.inertia, self.inertia_std, self.undetermined, axes)

    @property
    def precision(self) -> Precision:
        """The σ against :attr:`precision_target` (:func:`~rig_identification.estimation.precision.precision_of`):
        the entries short of it and the recording length that would reach it."""
        duration = (sum(float(s.t[-1] - s.t[0]) for s in self.series) if self.series
                    else float(self.t_end - self.t_start))
        return precision_of(self.inertia, self.inertia_std, self.undetermined, duration,
                            None if self.validation is None else self.validation.verdict, self.precision_target,
                            self.crb_std)

    @property
    def undetermined(self) -> tuple[str, ...]:
        """Entries the recording does not determine (validation verdict ``not_identifiable``):
        reported as None."""
        return () if self.validation is None else tuple(self.validation.undetermined)

    def to_dict(self, t0: float | list[float] | None = None) -> dict[str, Any]:
        """The result as JSON (schema :data:`~rig_identification.io.export.INERTIA_SCHEMA`, version
        :data:`~rig_identification.io.export.INERTIA_SCHEMA_VERSION`; ``units`` per field,
        :data:`~rig_identification.io.export.UNITS`).

        Tensor entries as geometry_msgs/Inertia (off-diagonals the negated products of inertia),
        body axes of rig.yaml; ``products_of_inertia`` with the vehicle-dynamics sign; the tensor
        about the body frame's origin; principal moments and axes.  Undetermined entries (and
        everything derived from them) are None, never NaN.  t0: the recording's first IMU stamp,
        s: ``window.start``/``end`` are then seconds from it (as ``--start`` takes them) and the
        absolute stamps are ``start_stamp``/``end_stamp``; without it (a stream, no first
        sample known) ``start``/``end`` are the absolute stamps too.  A joint fit takes one t0
        per recording (``series`` order): each of ``recordings`` gets its own window, and the
        overall ``window.start``/``end`` are None (no common origin).  The validation's time
        segments (``validation.segments[].start``/``end``) count from the same origin as their
        recording's window (the stamps in ``start_stamp``/``end_stamp``)."""
        theta = from_tensor(self.inertia)
        gone = set(self.undetermined)
        ex = express(self.mass, self.center_of_gravity, self.inertia, self.inertia_std, gone)
        num = finite_or_none

        def entry(k: str, v: float) -> float | None:
            return None if k in gone else num(v)

        def per_key(a: np.ndarray | None) -> dict[str, float | None] | None:
            return None if a is None else {k: num(v) for k, v in zip(KEYS, a)}

        def window(t_start: float, t_end: float, n: int, origin: float | None) -> dict[str, Any]:
            if origin is None:
                start, end = (None, None) if isinstance(t0, (list, tuple)) else (t_start, t_end)
            else:
                start, end = t_start - origin, t_end - origin
            return {"start": num(start), "end": num(end), "samples": int(n), "start_stamp": num(t_start),
                    "end_stamp": num(t_end)}

        origins = list(t0) if isinstance(t0, (list, tuple)) else [t0] * len(self.series)

        def segment_origins() -> list[float] | None:
            # the first IMU stamp of each validation segment's recording: a recording's segments
            # follow each other in series order, the first starting at its series' first sample
            v = self.validation
            if t0 is None or v is None or v.segment_times is None:
                return None
            if not isinstance(t0, (list, tuple)):
                return [t0] * len(v.segment_times)
            firsts = [float(s.t[0]) for s in self.series]
            out, i = [], -1
            for a, _ in v.segment_times:
                if i + 1 < len(firsts) and float(a) == firsts[i + 1]:
                    i += 1
                out.append(origins[max(i, 0)])
            return out  # type: ignore[return-value]  # t0 is a list here: origins = list(t0), no None

        scale = float(np.trace(self.inertia)) / 3 if np.all(np.isfinite(self.inertia)) else None
        weak = [describe_direction(s, D, scale=scale, weakest=i == 0, undetermined=gone)
                for i, (s, D) in enumerate(self.weak_directions)]
        pm = ex.principal_dict()
        units = dict(UNITS) if t0 is not None else UNITS | dict.fromkeys(
            ("window.start", "window.end", "validation.segments.start", "validation.segments.end"), "s, stamps")
        return {
            "schema": INERTIA_SCHEMA, "schema_version": INERTIA_SCHEMA_VERSION, "units": units,
            "mass": float(self.mass),
            "center_of_gravity": [float(x) for x in self.center_of_gravity],
            "validation": None if self.validation is None else self.validation.to_dict(segment_origins()),
            "inertia_about_cg": {k: entry(k, v) for k, v in zip(KEYS, theta)},
            "inertia_std": {k: entry(k, v) for k, v in zip(KEYS, self.inertia_std)},
            "inertia_crb_std": per_key(self.crb_std),
            "inertia_cg_std": per_key(self.cg_contribution_std),
            "precision": self.precision.to_dict(),
            "frame": "body",
            "convention": "; ".join(convention_lines(BODY)),
            "products_of_inertia": ex.products(),
            "inertia_about_origin": {k: ex.entry(k, "origin") for k in KEYS},
            "uncertainty": self.uncertainty,
            "weight_surplus": num(self.weight_surplus),
            "principal_moments": None if pm is None else pm["moments"],
            "principal_axes": None if pm is None else pm["axes"],
            "physically_consistent": bool(np.all(np.isfinite(self.inertia)) and physically_consistent(self.inertia)),
            "correlation": {"keys": list(KEYS),
                            "matrix": [[None if not np.isfinite(x) else round(float(x), 4) for x in row]
                                       for row in self.correlation]},
            "weakly_determined": weak,
            "window": window(self.t_start, self.t_end, self.n_samples, None if isinstance(t0, (list, tuple)) else t0),
            "band_hz": [num(self.band_hz[0]), num(self.band_hz[1])],
            "residual_rms_rad_s": [num(x) for x in self.residual_rms],
            "fit_r2": [num(x) for x in self.fit_r2],
            "method": self.method,
            "warnings": list(self.warnings),
        } | ({"recordings": [{"label": s.label, "window": window(float(s.t[0]), float(s.t[-1]), len(s.t), o),
                               "band_hz": [float(s.band_hz[0]), float(s.band_hz[1])],
                               "residual_rms_rad_s": [float(x) for x in np.sqrt(np.mean(s.residual**2, 0))]}
                              for s, o in zip(self.series, origins)]} if len(self.series) > 1 else {})


def compare_to_truth(result: InertiaResult, truth: dict[str, Any]) -> dict[str, dict[str, float]]:
    """Errors of the identified tensor against truth.yaml's ``inertia_about_cg``.

    Returns {key: {"value", "truth", "error", "error_percent", "error_sigma"}}; the
    percentage is of the entry for diagonals and of the largest diagonal for products.
    """
    tru = truth["inertia_about_cg"]
    refs = entry_scales([tru[k] for k in KEYS])
    out = {}
    for k, v, s, ref in zip(KEYS, from_tensor(result.inertia), result.inertia_std, refs):
        e = float(v - tru[k])
        out[k] = {"value": float(v), "truth": float(tru[k]), "error": e, "error_percent": 100 * e / ref,
                  "error_sigma": e / s if s > 0 else float(np.inf)}
    return out
