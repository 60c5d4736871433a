"""Recordings written: the sensor streams as a rosbag2 (MCAP or sqlite3), and a whole recording
folder (rig.yaml, bag/, truth.yaml) that appears atomically.

Messages as ``docs/recording_format.md`` (:mod:`~rig_identification.io.recording` lists the topics),
written with ``rosbags``; the bag timestamp of each message is its header stamp.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from .atomic import atomic_directory
from .bag_decode import IMU_TYPE, VECTOR_TYPE, WRENCH_TYPE
from .recording import (
    EXCITER_TOPIC,
    IMU_TOPIC,
    INCLINOMETER_TOPIC,
    LOAD_CELL_PREFIX,
    RecordingError,
    SensorData,
    TimeSeries,
    typestore,
)
from .rig import Rig, dump_rig

if TYPE_CHECKING:
    from rosbags.interfaces import Connection


def split_stamp(t: float) -> tuple[int, int]:
    """Float seconds -> (sec, nanosec) of a builtin_interfaces/Time, 0 <= nanosec < 1e9."""
    sec = math.floor(t)
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return int(sec), nsec


def _header(types: Mapping[str, Any], t: float, frame: str) -> Any:
    sec, nsec = split_stamp(t)
    return types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                        frame_id=frame)


def sensor_messages(rig: Rig, sensors: SensorData) -> Iterator[tuple[str, str, float, Any]]:
    """Yield ``(topic, msgtype, stamp_s, message)`` for every sample, in stamp order.

    Messages are rosbags typestore objects, ready for ``typestore.serialize_cdr``.
    """
    ts = typestore()
    T: Mapping[str, Any] = ts.types     # message classes by type name (rosbags builds them at run time)
    Vec, Quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    streams: list[tuple[str, str, TimeSeries, Callable[[float, np.ndarray], Any]]] = []
    zero_cov = np.zeros(9)
    orient_cov = np.zeros(9)
    orient_cov[0] = -1.0

    def imu_msg(t: float, row: np.ndarray) -> Any:
        return T[IMU_TYPE](header=_header(T, t, "imu"), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                           orientation_covariance=orient_cov,
                           angular_velocity=Vec(x=row[0], y=row[1], z=row[2]), angular_velocity_covariance=zero_cov,
                           linear_acceleration=Vec(x=row[3], y=row[4], z=row[5]),
                           linear_acceleration_covariance=zero_cov)

    def wrench_msg(frame: str, fx: int | None, fy: int | None, fz: int | None) -> Callable[[float, np.ndarray], Any]:
        def f(t: float, row: np.ndarray) -> Any:
            r = [0.0, 0.0, 0.0]
            vals = (fx, fy, fz)
            for i, v in enumerate(vals):
                if v is not None:
                    r[i] = float(row[v])
            return T[WRENCH_TYPE](header=_header(T, t, frame),
                                  wrench=T["geometry_msgs/msg/Wrench"](force=Vec(x=r[0], y=r[1], z=r[2]),
                                                                        torque=Vec(x=0.0, y=0.0, z=0.0)))
        return f

    def incl_msg(t: float, row: np.ndarray) -> Any:
        return T[VECTOR_TYPE](header=_header(T, t, "inclinometer"), vector=Vec(x=row[0], y=row[1], z=0.0))

    streams.append((IMU_TOPIC, IMU_TYPE, sensors.imu, imu_msg))
    for name, s in sensors.load_cells.items():
        streams.append((LOAD_CELL_PREFIX + name, WRENCH_TYPE, s, wrench_msg(f"load_cell_{name}", None, None, 0)))
    if sensors.exciter is not None:
        streams.append((EXCITER_TOPIC, WRENCH_TYPE, sensors.exciter, wrench_msg("exciter", 0, 1, None)))
    if sensors.inclinometer is not None:
        streams.append((INCLINOMETER_TOPIC, VECTOR_TYPE, sensors.inclinometer, incl_msg))
    events: list[tuple[float, int, int]] = []
    for k, (_, _, s, _) in enumerate(streams):
        events.extend((float(t), k, i) for i, t in enumerate(s.t))
    events.sort()
    for t, k, i in events:
        topic, mtype, s, make = streams[k]
        yield topic, mtype, t, make(t, s.data[i])


def write_bag(bag_dir: Path, rig: Rig, sensors: SensorData, storage: str = "mcap") -> int:
    """Write the sensor streams as a rosbag2 at ``bag_dir`` (must not exist).

    The bag timestamp of each message is its header stamp.  Returns the number of
    messages written.  ``storage``: ``"mcap"`` or ``"sqlite3"``.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = typestore()
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    n = 0
    with Writer(bag_dir, version=9, storage_plugin=plugin) as w:
        conns: dict[str, Connection] = {}
        for topic, mtype, t, msg in sensor_messages(rig, sensors):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, mtype, typestore=ts)
            w.write(conns[topic], int(round(t * 1e9)), ts.serialize_cdr(msg, mtype))
            n += 1
    return n


def write_recording(out: str | Path, rig: Rig, sensors: SensorData, truth: dict[str, Any] | None = None,
                    storage: str = "mcap", rig_comment: str | None = None, overwrite: bool = False) -> Path:
    """Write a recording folder atomically: it appears whole at ``out`` or not at all.

    Builds the folder next to ``out`` and renames it into place.  Raises
    :class:`RecordingError` if ``out`` exists and ``overwrite`` is false.
    """
    out = Path(out)
    if out.exists() and not overwrite:
        raise RecordingError(f"{out}: already exists (refusing to overwrite)")
    with atomic_directory(out, overwrite=overwrite) as tmp:
        (tmp / "rig.yaml").write_text(dump_rig(rig, rig_comment))
        if truth is not None:
            (tmp / "truth.yaml").write_text(yaml.safe_dump(truth, sort_keys=False, default_flow_style=None))
        write_bag(tmp / "bag", rig, sensors, storage)
    return out
