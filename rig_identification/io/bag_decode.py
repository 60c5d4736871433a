"""Bulk decoding of the rig's fixed-layout CDR messages: numpy over the raw bytes of many messages.

The stamped messages of the recording format (``docs/recording_format.md``) —
``sensor_msgs/msg/Imu``, ``geometry_msgs/msg/WrenchStamped``,
``geometry_msgs/msg/Vector3Stamped`` — are a ``std_msgs/msg/Header`` followed by float64
fields only.  In little-endian CDR (XCDR1, encapsulation ``00 01``; alignment counts from
the end of the 4-byte encapsulation header) one message with a ``frame_id`` of ``L - 1``
bytes is::

    offset          size  content
    0               4     encapsulation 00 01 (CDR_LE) + 2 option bytes (ignored)
    4               4     header.stamp.sec, int32
    8               4     header.stamp.nanosec, uint32
    12              4     L = frame_id length in bytes including its NUL, uint32
    16              L     frame_id bytes (UTF-8) and NUL
    16 + L          pad   zeros up to D
    D               8 n   the message's n float64 fields in declaration order

with ``D = 4 + ceil8(12 + L)`` and size ``D + 8 n``: every message of one type whose frame
ids have the same length has the same layout (the rules of OMG CDR 1.0 §15.3, as rosbags'
``serialize_cdr`` and rclcpp's Fast-CDR write them).

:func:`decode_stamped` reads the stamp and chosen float64 fields of many messages at once.
A message it cannot vouch for — not little-endian CDR, a size other than the layout's, a
frame id without its NUL or not UTF-8 — is left to the caller (``decoded`` False), who
deserialises it one at a time (rosbags), so that bulk and per-message reading agree
exactly, errors included.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, TypeAlias

import numpy as np

IMU_TYPE = "sensor_msgs/msg/Imu"
WRENCH_TYPE = "geometry_msgs/msg/WrenchStamped"
VECTOR_TYPE = "geometry_msgs/msg/Vector3Stamped"

#: What the readers take as a buffer of serialized messages: bytes-like, or a (B,) uint8 array.
BytesLike: TypeAlias = bytes | bytearray | memoryview | np.ndarray


def _xyz(name: str) -> tuple[str, ...]:
    return tuple(f"{name}.{c}" for c in "xyz")


def _matrix(name: str) -> tuple[str, ...]:
    return tuple(f"{name}[{i}]" for i in range(9))


#: The float64 fields after the header, in CDR order, for each fixed-layout type
#: (field paths as in the message definitions; ``[i]`` an element of a fixed array).
DOUBLE_FIELDS: dict[str, tuple[str, ...]] = {
    IMU_TYPE: (("orientation.x", "orientation.y", "orientation.z", "orientation.w")
               + _matrix("orientation_covariance")
               + _xyz("angular_velocity") + _matrix("angular_velocity_covariance")
               + _xyz("linear_acceleration") + _matrix("linear_acceleration_covariance")),
    WRENCH_TYPE: _xyz("wrench.force") + _xyz("wrench.torque"),
    VECTOR_TYPE: _xyz("vector"),
}

#: RIHS01 type hashes (REP 2011) of the layouts above: ``typestore.hash_rihs01(msgtype)`` of
#: rosbags' ``Stores.ROS2_JAZZY``, the same hashes ROS 2 Jazzy writes as
#: ``type_description_hash`` in metadata.yaml.  A bag whose embedded definition hashes
#: otherwise is not decoded in bulk.
TYPE_HASHES: dict[str, str] = {
    IMU_TYPE: "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
    WRENCH_TYPE: "RIHS01_8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77",
    VECTOR_TYPE: "RIHS01_d4829622288cbb443886e7ea94ea5671a3b1be6bab4ad04224432a65f7d7887a",
}

HEADER_BYTES = 16        # encapsulation, sec, nanosec, frame_id length: fixed for every layout

#: The fixed start of every layout (table above), packed little-endian.
HEADER = np.dtype({"names": ["enc0", "enc1", "sec", "nanosec", "frame_len"],
                   "formats": ["u1", "u1", "<i4", "<u4", "<u4"],
                   "offsets": [0, 1, 4, 8, 12], "itemsize": HEADER_BYTES})


class Decoded(NamedTuple):
    """Result of :func:`decode_stamped` for n messages.

    rows: (n, 1 + k) float64: header stamp ``sec + 1e-9 * nanosec``, s, then the k fields
    asked for, in their units.  decoded: (n,) bool; where False the row is NaN and the
    message must be deserialised on its own.
    """

    rows: np.ndarray
    decoded: np.ndarray


def payload_offset(frame_len: np.ndarray | int) -> np.ndarray | int:
    """Offset D of the first float64 after a header whose frame_id length field is
    ``frame_len`` (bytes including the NUL), from the start of the CDR data, bytes.
    (n,) int64 -> (n,) int64, or int -> int."""
    return 4 + (12 + frame_len + 7) // 8 * 8


def read_structs(buf: BytesLike, offsets: np.ndarray, dtype: np.dtype, checked: bool = True) -> np.ndarray:
    """The packed struct ``dtype`` found at each byte offset of ``buf``: (n,) array of dtype.

    buf: bytes-like or (B,) uint8 array.  offsets: (n,) int, any byte alignment (a view
    of buf with a stride of one byte, indexed once: no per-byte index array).  checked:
    False when the caller has already bounded the offsets (saves two passes over them).
    Raises ValueError (checked) or IndexError if a struct would reach outside buf.
    """
    offsets = np.asarray(offsets, np.int64)
    size = memoryview(buf).nbytes  # type: ignore[arg-type]  # numpy stubs: ndarray.__buffer__ only on Python >= 3.12
    if checked and len(offsets) and (offsets.min() < 0 or offsets.max() + dtype.itemsize > size):
        raise ValueError(f"struct of {dtype.itemsize} bytes outside the buffer of {size} bytes")
    if size < dtype.itemsize:
        return np.zeros(0, dtype)
    # gathered as plain bytes (numpy copies void items with memcpy; a structured gather
    # goes field by field, 3x slower), then viewed as the struct
    raw = np.dtype((np.void, dtype.itemsize))
    structs: np.ndarray = np.ndarray((size - dtype.itemsize + 1,), raw, buf, 0, (1,))[offsets].view(dtype)
    return structs


def _frame_ok(frame_ids: np.ndarray) -> np.ndarray:
    """(n,) void items of L bytes (frame id + NUL) -> (n,) bool: NUL-terminated and valid
    UTF-8, as rosbags checks and decodes a string (a bulk reader must fail where it fails).
    Each distinct frame id is decoded once (a topic nearly always has one)."""
    ok = np.ones(len(frame_ids), bool)
    if not len(frame_ids):
        return ok
    same = frame_ids == frame_ids[0]
    rest = np.nonzero(~same)[0]
    uniq, inverse = (np.unique(frame_ids[rest], return_inverse=True) if len(rest)
                     else (frame_ids[:0], np.zeros(0, np.intp)))
    for k, item in enumerate([frame_ids[0], *uniq]):
        raw = item.tobytes()
        try:
            good = raw[-1] == 0 and raw[:-1].decode() is not None
        except UnicodeDecodeError:
            good = False
        if not good:
            ok[same if k == 0 else rest[inverse.ravel() == k - 1]] = False
    return ok


def decode_stamped(buf: BytesLike, offsets: np.ndarray, sizes: np.ndarray, msgtype: str,
                   fields: Sequence[str]) -> Decoded:
    """Header stamps and float64 ``fields`` of n serialized messages of ``msgtype``.

    buf: bytes-like or (B,) uint8 array holding the messages; message i is
    ``buf[offsets[i]:offsets[i] + sizes[i]]`` (CDR with its 4-byte encapsulation header, as
    rosbag2 stores it).  offsets, sizes: (n,) int.  msgtype: a key of
    :data:`DOUBLE_FIELDS`.  fields: names from ``DOUBLE_FIELDS[msgtype]``, e.g.
    ``"angular_velocity.x"``.

    Groups the messages by frame id length (one layout each) and reads each group's values
    with one strided gather.  Values are the exact float64 of the message; the stamp is
    computed as the per-message reader computes it (``sec + 1e-9 * nanosec`` in float64).
    Messages that are not little-endian CDR of exactly the layout's size, or whose frame
    id lacks its NUL or is not UTF-8, come back with ``decoded`` False.

    Raises KeyError for a msgtype without a fixed layout or a field it does not have;
    ValueError if a message lies outside buf.
    """
    names = DOUBLE_FIELDS[msgtype]
    picks = np.array([names.index(f) for f in fields], np.int64)
    offsets = np.asarray(offsets, np.int64)
    sizes = np.asarray(sizes, np.int64)
    n = len(offsets)
    rows = np.full((n, 1 + len(picks)), np.nan)
    decoded = np.zeros(n, bool)
    if not n:
        return Decoded(rows, decoded)
    nbytes = memoryview(buf).nbytes  # type: ignore[arg-type]  # numpy stubs: ndarray.__buffer__ only on Python >= 3.12
    if offsets.min() < 0 or (offsets + sizes).max() > nbytes:
        raise ValueError(f"message bytes outside the buffer of {nbytes} bytes")
    # every read below stays inside its message: header (sizes >= 16), frame id and values
    # (sizes == the layout's size)
    cand = np.nonzero(sizes >= HEADER_BYTES)[0]
    head = read_structs(buf, offsets[cand], HEADER, checked=False)
    frame_len = head["frame_len"].astype(np.int64)
    fit = ((head["enc0"] == 0) & (head["enc1"] == 1) & (frame_len >= 1)
           & (sizes[cand] == payload_offset(frame_len) + 8 * len(names)))
    if not fit.all():
        cand, head, frame_len = cand[fit], head[fit], frame_len[fit]
    if not len(cand):
        return Decoded(rows, decoded)
    lo = int(picks.min()) if len(picks) else 0
    span = np.dtype([("v", "<f8", (int(picks.max()) - lo + 1 if len(picks) else 1,))])
    uniform = frame_len[0] == frame_len.min() == frame_len.max()   # one frame id length: the usual case
    for length in ([int(frame_len[0])] if uniform else np.unique(frame_len).tolist()):
        g = np.arange(len(cand)) if uniform else np.nonzero(frame_len == length)[0]
        offs = offsets[cand[g]]
        good = _frame_ok(read_structs(buf, offs + HEADER_BYTES, np.dtype((np.void, length)), checked=False))
        idx, h = cand[g[good]], head[g[good]]
        values = read_structs(buf, offs[good] + payload_offset(length) + 8 * lo, span, checked=False)["v"]
        rows[idx, 0] = h["sec"].astype(np.float64) + 1e-9 * h["nanosec"].astype(np.float64)
        rows[idx, 1:] = values[:, picks - lo]
        decoded[idx] = True
    return Decoded(rows, decoded)


__all__ = ["DOUBLE_FIELDS", "TYPE_HASHES", "HEADER", "Decoded", "decode_stamped", "read_structs",
           "payload_offset", "IMU_TYPE", "WRENCH_TYPE", "VECTOR_TYPE"]
