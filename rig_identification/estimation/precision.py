"""Precision against a lab's target: does a predicted σ give every entry to ±``target`` (95 %)?

``rig-identify plan`` predicts each run's σ (the rig model's Cramér–Rao bound of the planned run):
a verdict ``ok`` would say the σ are honest, not that they are small, and a lab that asks for 1 %
must hear whether a run reaches it and what would.  :func:`precision_of` compares each entry's
95 % half-width, 1.96 σ, with the target on the entry's scale (a moment's own magnitude, the
largest moment's for a product: :func:`~rig_identification.model.parametrisation.entry_scales`)
and gives the run length that would reach it: the asymptotic covariance of a prediction-error
estimate falls as 1/N with the number of samples N of a stationary excitation (Ljung 1999,
*System Identification*, §9.2, Theorem 9.1: covariance P/N), so σ ∝ 1/√T and the length needed
is T·(half-width / target)² at the same excitation.  A stronger or better-placed excitation
reaches the target too: the plan says which.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..io.export import SYMBOL
from ..io.verdict import KEYS, Z95
from ..model.parametrisation import entry_scales, from_tensor

TARGET = 0.01               # the default target: ±1 % at 95 %


@dataclass(frozen=True)
class Precision:
    """Predicted σ against ``target``.

    target: the 95 % half-width asked of every entry, a fraction of its scale (0.01: ±1 %);
    half_width: entry key → 1.96 σ / scale, a fraction, keys in
    :data:`~rig_identification.io.verdict.KEYS` order; short: the entries beyond the target;
    duration: s, the run's length; length_factor: the run length, as a multiple of ``duration``,
    that would bring every entry within the target at the same excitation (σ ∝ 1/√T, Ljung 1999
    Theorem 9.1), None where every entry meets it; subject: what the duration is of, in the text
    ("each planned run's")."""

    target: float
    half_width: dict[str, float]
    short: tuple[str, ...]
    duration: float
    length_factor: float | None
    subject: str = "each planned run's"

    @property
    def met(self) -> bool:
        """Every entry within the target."""
        return not self.short

    def text(self) -> str:
        """One line of ``rig-identify plan``'s text output."""
        head = f"precision (95 %, target ±{100 * self.target:.3g} % of each moment, products of the largest): "
        if self.met:
            worst = max(KEYS, key=lambda k: self.half_width[k])
            return head + f"every entry within it (the widest: {SYMBOL[worst]} ±{100 * self.half_width[worst]:.2g} %)"
        widths = ", ".join(f"{SYMBOL[k]} ±{100 * self.half_width[k]:.2g} %" for k in self.short)
        factor = float(self.length_factor or 1.0)
        return (head + f"{widths}: short of the target — about {factor:.2g}× {self.subject} {self.duration:.0f} s "
                f"({factor * self.duration:.0f} s) at the same excitation would reach it, or a stronger or "
                "better-placed one")

    def to_dict(self) -> dict[str, Any]:
        """JSON: ``target``, ``half_width`` (fractions), ``short``, ``met``, ``duration_s``,
        ``length_factor``, ``text``."""
        return {"target": self.target, "half_width": dict(self.half_width), "short": list(self.short),
                "met": self.met, "duration_s": self.duration, "length_factor": self.length_factor,
                "text": self.text()}


def precision_of(inertia: np.ndarray, std: np.ndarray, duration: float, target: float = TARGET,
                 subject: str = "each planned run's") -> Precision:
    """The :class:`Precision` of σ ``std`` against ``target``.

    inertia: (3,3) kg·m² about the CG; std: (6,) kg·m², σ of the entries in
    :data:`~rig_identification.io.verdict.KEYS` order; duration: s, the run's length; target: a
    fraction > 0; subject: what ``duration`` is of, for the text.  Raises ValueError for a target
    that is not a positive finite number, or a σ or a scale that is not positive and finite."""
    if not (np.isfinite(target) and target > 0):
        raise ValueError(f"precision target must be a positive fraction, got {target!r}")
    scale = entry_scales(from_tensor(np.asarray(inertia, float)))
    std = np.asarray(std, float)
    if not (np.all(np.isfinite(std)) and np.all(std > 0) and np.all(np.isfinite(scale)) and np.all(scale > 0)):
        raise ValueError(f"precision: σ {std} and the entries' scales {scale} must be positive and finite")
    width = Z95 * std / scale
    hw = {k: float(w) for k, w in zip(KEYS, width)}
    short = tuple(k for k in KEYS if hw[k] > target)
    factor = float(max(hw[k] for k in short) / target) ** 2 if short else None
    return Precision(float(target), hw, short, float(duration), factor, subject)


__all__ = ["Precision", "TARGET", "precision_of"]
