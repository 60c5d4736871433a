"""The names every result shares: the tensor entries' :data:`KEYS`, the 95 % interval's :data:`Z95`,
the share :data:`DETERMINED_SHARE` within which an entry is determined (:func:`entry_determined`),
one validation :class:`Check` (the static test's, :mod:`rig_identification.statics.validation`), and
the package's name and installed version that every ``--version`` and every report states
(:data:`PACKAGE`, :func:`package_version`).  Standard library only, so that a ``--version`` loads
nothing else."""
from __future__ import annotations

import math
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from typing import Any

PACKAGE = "rig_identification"

KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
#: The normal distribution's 97.5 % quantile: ±Z95·σ holds 95 %.
Z95 = 1.959963984540054
#: A tensor entry is determined when its 95 % half-width is within this share of its scale (a
#: moment's own, the largest moment's for a product).
DETERMINED_SHARE = 0.01


def entry_determined(share: float) -> bool:
    """Whether an entry whose σ is ``share`` of its scale is determined: its 95 % half-width
    Z95·σ within :data:`DETERMINED_SHARE` of that scale (False for a non-finite σ)."""
    return bool(Z95 * share <= DETERMINED_SHARE)


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
            return None if x is None or not math.isfinite(x) else float(x)
        return {"name": self.name, "statistic": num(self.statistic), "threshold": num(self.threshold),
                "passed": self.passed, "detail": self.detail, "sigma_factor": float(self.sigma_factor)}


def package_version() -> str:
    """The installed version of this package (``importlib.metadata``), or "unknown (not
    installed)" when it is run from a source tree that was not installed."""
    try:
        return version(PACKAGE)
    except PackageNotFoundError:
        return "unknown (not installed)"
