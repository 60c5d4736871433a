"""How the cables are modelled in a simulation: tension-only spring-dampers or inextensible links.

The equations of each model: :mod:`~rig_identification.model.dynamics`.  The defaults are the
reference simulator's: stiffness 5e6 N/m (unless rig.yaml gives the cable's), damping
c = 2 ζ sqrt(k m / N) with ζ = 0.01.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..io.rig import Rig

DEFAULT_STIFFNESS = 5.0e6          # N/m, reference simulator's cable stiffness
DEFAULT_DAMPING_RATIO = 0.01       # ζ of the default cable damping (reference simulator)
DEFAULT_BAUMGARTE = 20.0           # 1/s


@dataclass(frozen=True)
class CableModel:
    """How the cables are modelled.

    type: ``"spring"`` or ``"inextensible"``.  stiffness, damping: (N,) N/m and N·s/m
    (spring only, else ``None``).  baumgarte: β, 1/s, and compression: links that may push
    (inextensible only).
    """

    type: str
    stiffness: np.ndarray | None = None
    damping: np.ndarray | None = None
    baumgarte: float = DEFAULT_BAUMGARTE
    compression: bool = False

    @staticmethod
    def spring(rig: Rig, mass: float, stiffness: ArrayLike | None = None, damping: ArrayLike | None = None,
               damping_ratio: float = DEFAULT_DAMPING_RATIO) -> "CableModel":
        """Spring-damper cables.  ``stiffness``/``damping``: scalar, (N,) or None (defaults:
        rig.yaml stiffness else 5e6 N/m; c = 2 ζ sqrt(k m / N))."""
        n = len(rig.cables)
        if stiffness is None:
            k = np.array([DEFAULT_STIFFNESS if c.stiffness is None else c.stiffness for c in rig.cables])
        else:
            k = np.broadcast_to(np.asarray(stiffness, float), (n,)).copy()
        if damping is None:
            c = 2.0 * damping_ratio * np.sqrt(k * mass / n)
        else:
            c = np.broadcast_to(np.asarray(damping, float), (n,)).copy()
        return CableModel("spring", k, c)

    @staticmethod
    def inextensible(baumgarte: float = DEFAULT_BAUMGARTE, compression: bool = False) -> "CableModel":
        return CableModel("inextensible", baumgarte=baumgarte, compression=compression)

    def describe(self) -> dict[str, Any]:
        if self.type == "spring":
            assert self.stiffness is not None and self.damping is not None   # a spring model has both
            return {"type": "spring", "cable_stiffness": self.stiffness.tolist(),
                    "cable_damping": self.damping.tolist(),
                    "cable_tension_model": "max(0, stiffness*(length-length0) + damping*d(length)/dt), "
                                           "along the cable"}
        return {"type": "inextensible", "baumgarte": self.baumgarte, "compression": self.compression,
                "cable_tension_model": "Lagrange multipliers of |ceiling_anchor - body_anchor| = length "
                                       "(KKT each step, Baumgarte stabilisation)"}
