"""Node parameters turned into core objects: the rig description named by the ``rig`` parameter,
and a parameter for every keyword argument of a core function (the core's default)."""
from __future__ import annotations

import inspect
from pathlib import Path

from rclpy.node import Node

from ..io.rig import Rig, RigError
from ..model.experiment import load_rig_or_experiment


def load_rig_source(path: str | Path) -> Rig:
    """The rig description of ``path``: a rig.yaml, a recording folder (its rig.yaml) or an
    experiment file (its ``rig:`` section, as ``config/rigs/default.yaml``: what the
    sensor_driver's simulation of that file writes as rig.yaml, unless the experiment has
    effects that change rig.yaml — then give the driver's ``rig_out`` file).

    Raises :class:`~rig_identification.io.rig.RigError` naming the file (missing file, no
    rig.yaml in the folder, bad field)."""
    p = Path(path)
    if p.is_dir():
        if not (p / "rig.yaml").is_file():
            raise RigError(f"{p}: a folder without rig.yaml (expected a rig.yaml, an experiment file or a "
                           "recording folder)")
        p = p / "rig.yaml"
    return load_rig_or_experiment(p)


def load_rig_param(node: Node) -> Rig:
    """Load the rig description named by the node's ``rig`` parameter: a rig.yaml, a
    recording folder or an experiment file (:func:`load_rig_source`).

    Raises :class:`~rig_identification.io.rig.RigError` with a clear message.
    """
    path = node.get_parameter("rig").value
    if not path:
        raise RigError("parameter 'rig' is empty: give the path of the rig description, "
                       "e.g. --ros-args -p rig:=/path/to/rig.yaml")
    return load_rig_source(path)


def core_params(node: Node, func, skip=()) -> dict:
    """Declare a ROS parameter for every keyword argument of the core function ``func`` whose
    default is a number, bool or string (the core's own default, so node and core never
    disagree) and return the current values, ready to pass as ``**kwargs``."""
    out = {}
    for name, p in inspect.signature(func).parameters.items():
        if name in skip or p.default is inspect.Parameter.empty:
            continue
        if isinstance(p.default, (bool, int, float, str)):
            node.declare_parameter(name, p.default)
            out[name] = node.get_parameter(name).value
    return out
