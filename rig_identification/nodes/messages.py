"""Reading and writing message fields one message at a time: header stamps, 3-vectors, and
JSON payloads of std_msgs/String and std_srvs/Trigger (the batch codec is :mod:`.codec`)."""
from __future__ import annotations

import json
import math

from ..io.recording_writer import split_stamp


def stamp_to_sec(stamp) -> float:
    """builtin_interfaces/Time -> float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def set_stamp(header, t: float, frame_id: str | None = None) -> None:
    """Write float seconds ``t`` (and optionally the frame id) into a std_msgs/Header in place."""
    header.stamp.sec, header.stamp.nanosec = split_stamp(t)
    if frame_id is not None:
        header.frame_id = frame_id


def xyz(v) -> tuple[float, float, float]:
    """geometry_msgs Vector3/Point -> tuple."""
    return (v.x, v.y, v.z)


def set_xyz(msg_vec, values) -> None:
    msg_vec.x, msg_vec.y, msg_vec.z = (float(values[0]), float(values[1]), float(values[2]))


def to_json(obj) -> str:
    """JSON with NaN/inf written as null (strict JSON readers reject NaN)."""
    def clean(o):
        if isinstance(o, float):
            return o if math.isfinite(o) else None
        if isinstance(o, dict):
            return {str(k): clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        if hasattr(o, "tolist"):
            return clean(o.tolist())
        return o
    return json.dumps(clean(obj))
