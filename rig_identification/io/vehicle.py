"""Where the vehicle lies in rig.yaml's body frame, and what follows from it: the vehicle axes
(SAE J670, ISO 8855) as a turn of the body axes, and which body axis roll, pitch and yaw are about.

The body frame of rig.yaml is right-handed (REP-103) and fixed to the carrying frame; nothing
says the vehicle's front is along its x.  rig.yaml ``body.vehicle`` says where it is:
``{front: +y, top: +z}`` — the body axis that points to the vehicle's front and the one that
points to its top, each one of ``+x -x +y -y +z -z``, on two different axes.  The vehicle's left
is then top × front.  Roll is the rotation about the front–rear axis, pitch about the lateral
axis, yaw about the top–bottom axis (SAE J670, ISO 8855).  Without ``body.vehicle`` (the
default) the vehicle's orientation is unknown: no output calls a moment roll, pitch or yaw, and
the vehicle axes cannot be formed (:class:`AxesError`).

Vehicle axes (:data:`VEHICLE_AXES`; vectors in them = R @ vectors in body axes, R a proper
rotation whose rows are the vehicle axes in body coordinates):

* ``sae``: SAE J670, x forward, y right, z down: R = [front; −left; −top].
* ``iso8855``: ISO 8855, x forward, y left, z up: R = [front; left; top].

Each R is a signed permutation (front and top are body axes), so each entry of the tensor
R J Rᵀ is one entry of J, its sign perhaps flipped.  Pure numpy; no ROS.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

SIGNED_AXES = ("+x", "-x", "+y", "-y", "+z", "-z")
"""The values of ``body.vehicle.front`` and ``body.vehicle.top``: a body axis and its sense."""
MOTIONS = ("roll", "pitch", "yaw")
"""The vehicle's rotations, in this order: about its front–rear, lateral and top–bottom axes."""
VEHICLE_AXES = {"sae": ("SAE J670", "x forward, y right, z down"),
                "iso8855": ("ISO 8855", "x forward, y left, z up")}
"""The vehicle axes that can be asked for (``--axes``, rig.yaml ``output_axes``): name ->
(standard, directions)."""


class AxesError(ValueError):
    """Axes that cannot be formed: vehicle axes asked for without ``body.vehicle``, or an unknown name."""


def axis_vector(name: str) -> np.ndarray:
    """(3,) unit vector of a signed body axis (one of :data:`SIGNED_AXES`)."""
    v = np.zeros(3)
    v["xyz".index(name[1])] = 1.0 if name[0] == "+" else -1.0
    return v


@dataclass(frozen=True)
class Vehicle:
    """The vehicle's orientation in a set of axes: ``front`` and ``top``, each one of
    :data:`SIGNED_AXES`, on different axes (ValueError otherwise)."""

    front: str
    top: str

    def __post_init__(self) -> None:
        for what, v in (("front", self.front), ("top", self.top)):
            if v not in SIGNED_AXES:
                raise ValueError(f"{what} must be one of {', '.join(SIGNED_AXES)}, got {v!r}")
        if self.front[1] == self.top[1]:
            raise ValueError(f"front {self.front} and top {self.top} lie on the same axis")

    @property
    def forward(self) -> np.ndarray:
        """(3,) unit vector to the vehicle's front."""
        return axis_vector(self.front)

    @property
    def up(self) -> np.ndarray:
        """(3,) unit vector to the vehicle's top."""
        return axis_vector(self.top)

    @property
    def left(self) -> np.ndarray:
        """(3,) unit vector to the vehicle's left: top × front."""
        return np.cross(self.up, self.forward)

    def motion(self, axis: int) -> str:
        """The rotation about axis ``axis`` (0 x, 1 y, 2 z): roll (the front's axis), yaw (the
        top's) or pitch (the third)."""
        if axis == "xyz".index(self.front[1]):
            return "roll"
        return "yaw" if axis == "xyz".index(self.top[1]) else "pitch"

    def text(self) -> str:
        """``the vehicle's front along +y, its top along +z``."""
        return f"the vehicle's front along {self.front}, its top along {self.top}"

    def to_dict(self) -> dict[str, str]:
        """rig.yaml's ``body.vehicle`` mapping."""
        return {"front": self.front, "top": self.top}


def vehicle_rotation(vehicle: Vehicle, name: str) -> np.ndarray:
    """(3,3) proper rotation R from the body axes to the vehicle axes ``name`` (a key of
    :data:`VEHICLE_AXES`): vectors in them = R @ vectors in body axes; the tensor R J Rᵀ."""
    f, left, u = vehicle.forward, vehicle.left, vehicle.up
    if name == "sae":
        return np.array([f, -left, -u]) + 0.0     # + 0.0: no negative zeros
    if name == "iso8855":
        return np.array([f, left, u]) + 0.0
    raise AxesError(f"no vehicle axes {name!r} (known: {', '.join(VEHICLE_AXES)})")


def common_vehicle(vehicles: Iterable[Vehicle | None]) -> tuple[Vehicle | None, str | None]:
    """The vehicle's orientation several rig.yaml state (None: not stated): the one they state
    when those that state one agree; else None and a warning."""
    stated = {v for v in vehicles if v is not None}
    if len(stated) <= 1:
        return (stated.pop() if stated else None), None
    said = "; ".join(sorted(f"front {v.front}, top {v.top}" for v in stated))
    return None, (f"the recordings' rig.yaml state different body.vehicle ({said}): the vehicle's orientation is "
                  "taken as unknown (no roll, pitch, yaw; no vehicle axes)")


__all__ = ["MOTIONS", "SIGNED_AXES", "VEHICLE_AXES", "AxesError", "Vehicle", "axis_vector", "common_vehicle",
           "vehicle_rotation"]
