"""Where a node process finds the package's files and the environment it runs in: the
package's data files (colcon share directory or source tree), the default experiment, the Fast
DDS participant profile, and the environment of a child process of an isolated graph."""
from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

PACKAGE = "rig_identification"


def package_file(relpath: str) -> Path:
    """A data file of the package: the colcon share directory when installed with colcon
    (found through the ament index), else the source tree (pip editable install, repo)."""
    try:
        from ament_index_python.packages import get_package_share_directory
        p = Path(get_package_share_directory(PACKAGE)) / relpath
        if p.exists():
            return p
    except Exception:  # PackageNotFoundError, or no ament index at all
        pass
    here = Path(__file__).resolve().parent.parent  # rig_identification/
    for base in (here / "data", here.parent):
        p = base / relpath
        if p.exists():
            return p
    return here.parent / relpath


def default_experiment() -> Path:
    """The embedded default experiment ``config/rigs/default.yaml``."""
    return package_file("config/rigs/default.yaml")


DDS_PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")  # Fast DDS 2.x, 3.x


def dds_profile(env: MutableMapping[str, str] | None = None) -> None:
    """Point Fast DDS at the package's participant profile ``config/dds/fastdds.xml`` (a 3 s
    participant lease instead of 20 s: a killed node's readers stop holding the reliable
    KEEP_ALL writers back after 3 s) unless a profile file is set already
    (``FASTRTPS_DEFAULT_PROFILES_FILE``, read by Fast DDS 2.x as in Jazzy, or
    ``FASTDDS_DEFAULT_PROFILES_FILE``, 3.x).  ``env``: the environment to change (default
    ``os.environ``; call before ``rclpy.init``)."""
    env = os.environ if env is None else env
    if any(env.get(v) for v in DDS_PROFILE_VARS):
        return
    p = package_file("config/dds/fastdds.xml")
    if p.exists():
        for v in DDS_PROFILE_VARS:
            env[v] = str(p)


def ros_env(domain_id: int, base: dict | None = None) -> dict:
    """Environment for a child process of an isolated graph: ``ROS_DOMAIN_ID`` and discovery
    limited to this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``); Python output
    unbuffered so that logs arrive in order."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    env["PYTHONUNBUFFERED"] = "1"
    env.setdefault("RCUTILS_COLORIZED_OUTPUT", "0")
    dds_profile(env)
    return env
