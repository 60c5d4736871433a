"""Recordings: the rig's sensor streams as arrays, read from rosbag2.

A recording folder (``docs/recording_format.md``) holds ``rig.yaml``, ``bag/`` (rosbag2,
MCAP or sqlite3) and, for simulated recordings, ``truth.yaml``.  Bags are read and
written with ``rosbags`` (no ROS installation needed); the rig topics are read in bulk,
numpy over the raw CDR bytes (:mod:`rig_identification.io.bag_raw`,
:mod:`rig_identification.io.bag_decode`), with rosbags'
per-message deserialisation as the reference and the fallback.

Topics (all stamped; consumers align them by ``header.stamp``):

* ``/rig/imu`` sensor_msgs/msg/Imu, frame ``imu``: gyro rad/s, specific force m/s^2.
* ``/rig/load_cells/<cable>`` geometry_msgs/msg/WrenchStamped: ``wrench.force.z`` = tension, N.
* ``/rig/exciter/wrench`` geometry_msgs/msg/WrenchStamped: ``force.x``, ``force.y`` in the exciter frame, N.
* ``/rig/inclinometer`` geometry_msgs/msg/Vector3Stamped: ``vector.x``/``vector.y`` elevation of the
  inclinometer's x/y axes above the horizontal, rad.

Writing a recording: :mod:`~rig_identification.io.recording_writer`; the spans a fit must leave
out (gaps, saturation, slack cables): :mod:`~rig_identification.io.quality`.

Errors: :class:`RecordingError` (a ``ValueError``) naming the file and topic.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np
import yaml

from .bag_decode import IMU_TYPE, TYPE_HASHES, VECTOR_TYPE, WRENCH_TYPE, BytesLike, decode_stamped
from .bag_raw import read_topics
from .rig import Rig, Topics, load_rig
from .stamps import regular_stamps

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import Connection
    from rosbags.typesys.store import Typestore

# the streams' own names (docs/recording_format.md); a bag recorded under other names maps them
# with rig.yaml ``topics`` (:class:`~rig_identification.io.rig.Topics`)
IMU_TOPIC = Topics.imu
LOAD_CELL_PREFIX = Topics.load_cells
EXCITER_TOPIC = Topics.exciter
INCLINOMETER_TOPIC = Topics.inclinometer


class RecordingError(ValueError):
    """A recording that cannot be read or is inconsistent with its rig description."""


@dataclass(frozen=True)
class TimeSeries:
    """Samples of one stream.  t: (N,) header stamps, s.  data: (N, k)."""

    t: np.ndarray
    data: np.ndarray

    def __post_init__(self) -> None:
        data = np.asarray(self.data, float)
        object.__setattr__(self, "t", np.asarray(self.t, float))     # frozen: the arrays made once, here
        object.__setattr__(self, "data", data[:, None] if data.ndim == 1 else data)

    def __len__(self) -> int:
        return len(self.t)

    def window(self, t0: float, t1: float) -> "TimeSeries":
        m = (self.t >= t0) & (self.t <= t1)
        return TimeSeries(self.t[m], self.data[m])

    def interp(self, t: np.ndarray) -> np.ndarray:
        """Linear interpolation of every column at times ``t`` (M,) -> (M, k)."""
        return np.column_stack([np.interp(t, self.t, c) for c in self.data.T])


@dataclass(frozen=True)
class SensorData:
    """All sensor streams of one experiment.

    imu.data: (N, 6) gyro x,y,z rad/s then specific force x,y,z m/s^2, IMU axes.
    load_cells[name].data: (N, 1) cable tension, N.
    exciter.data: (N, 2) exciter force x, y in the exciter frame, N (or None).
    inclinometer.data: (N, 2) elevation of the x and y axes, rad (or None).
    """

    imu: TimeSeries
    load_cells: dict[str, TimeSeries]
    exciter: TimeSeries | None = None
    inclinometer: TimeSeries | None = None

    @property
    def t_start(self) -> float:
        return float(self.imu.t[0])

    @property
    def t_end(self) -> float:
        return float(self.imu.t[-1])


@dataclass(frozen=True)
class Recording:
    """A recording folder in memory: rig description, sensor data, optional truth."""

    rig: Rig
    sensors: SensorData
    truth: dict[str, Any] | None = None
    path: Path | None = None
    warnings: list[str] = field(default_factory=list)


# --- reading --------------------------------------------------------------------------

#: A topic whose write order departs from its stamp order by less than this fraction of its
#: sampling period is sorted silently: the format says a consumer aligns by stamp, and
#: drivers that stamp at acquisition and publish from several threads write so.  Not 1:
#: float64 stamps near 1.75e9 s resolve 2.4e-7 s (2.4e-4 of a 1 kHz period), and two
#: neighbours of a regular stream written swapped — a disorder of exactly one period — warn.
QUIET_DISORDER = 0.99


def typestore() -> Typestore:
    """rosbags' ROS 2 Jazzy type store (message classes and CDR serialisation)."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def _stamp(msg: Any) -> float:
    stamp: float = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
    return stamp


def _message_row(topic: str, msg: Any) -> tuple[float, ...]:
    """One row of a topic's samples from a deserialised message: stamp, s, then the values
    :func:`_bulk_fields` names, in the same order."""
    if topic == IMU_TOPIC:
        w, a = msg.angular_velocity, msg.linear_acceleration
        return (_stamp(msg), w.x, w.y, w.z, a.x, a.y, a.z)
    if topic == EXCITER_TOPIC:
        return (_stamp(msg), msg.wrench.force.x, msg.wrench.force.y)
    if topic == INCLINOMETER_TOPIC:
        return (_stamp(msg), msg.vector.x, msg.vector.y)
    return (_stamp(msg), msg.wrench.force.z)


def _bulk_fields(topic: str) -> tuple[str, ...]:
    """The float64 fields (:data:`~rig_identification.io.bag_decode.DOUBLE_FIELDS` names) of :func:`_message_row`."""
    if topic == IMU_TOPIC:
        return ("angular_velocity.x", "angular_velocity.y", "angular_velocity.z",
                "linear_acceleration.x", "linear_acceleration.y", "linear_acceleration.z")
    if topic == EXCITER_TOPIC:
        return ("wrench.force.x", "wrench.force.y")
    if topic == INCLINOMETER_TOPIC:
        return ("vector.x", "vector.y")
    return ("wrench.force.z",)


def _deserialize(reader: AnyReader, bag: Path, conn_topic: str, msgtype: str, raw: bytes) -> object:
    from rosbags.highlevel import AnyReaderError
    try:
        return reader.deserialize(raw, msgtype)
    except AnyReaderError as e:
        raise RecordingError(f"{bag}: topic {conn_topic}: cannot decode a {msgtype} message ({e})") from None


def _open_reader(bag: Path, bulk: bool) -> AnyReader:
    """An open AnyReader.  Bulk reading builds the default typestore (0.1 s) only for a
    bag without embedded message definitions; the per-message path builds it always, as
    it always has."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    if bulk:
        reader = AnyReader([bag])
        try:
            reader.open()
            return reader
        except AnyReaderError:
            pass   # no definitions in the bag (or unreadable: the second open says why)
    reader = AnyReader([bag], default_typestore=typestore())
    reader.open()
    return reader


def _per_message_rows(reader: AnyReader, bag: Path, conns: Sequence[Connection],
                      canon: dict[str, str]) -> dict[str, list[tuple[float, ...]]]:
    """Rows of every wanted message, deserialised one at a time (the reference path); keys the
    bag's topic names, ``canon`` maps them to the streams' own."""
    columns: dict[str, list[tuple[float, ...]]] = {}
    for conn, _, raw in reader.messages(connections=conns):
        msg = _deserialize(reader, bag, conn.topic, conn.msgtype, raw)
        columns.setdefault(conn.topic, []).append(_message_row(canon[conn.topic], msg))
    return columns


def _bulk_rows(reader: AnyReader, bag: Path, conns: Sequence[Connection],
               canon: dict[str, str]) -> dict[str, np.ndarray]:
    """Rows of every wanted message, decoded in bulk (:mod:`rig_identification.io.bag_decode`) over the raw bytes
    (:mod:`rig_identification.io.bag_raw`); messages the bulk decoder does not vouch for, and topics whose type
    definition in the bag is not the standard one, are deserialised one at a time."""
    msgtypes = {c.topic: c.msgtype for c in conns}
    standard = {}
    for mtype in set(msgtypes.values()):
        try:
            standard[mtype] = reader.typestore.hash_rihs01(mtype) == TYPE_HASHES[mtype]
        except Exception:  # noqa: BLE001 - an incomplete definition: rosbags will say what is wrong
            standard[mtype] = False

    def decode(topic: str, buf: BytesLike, offsets: np.ndarray, sizes: np.ndarray) -> np.ndarray:
        mtype = msgtypes[topic]
        if standard[mtype]:
            rows, done = decode_stamped(buf, offsets, sizes, mtype, _bulk_fields(canon[topic]))
        else:
            rows = np.full((len(offsets), 1 + len(_bulk_fields(canon[topic]))), np.nan)
            done = np.zeros(len(offsets), bool)
        view = memoryview(buf)  # type: ignore[arg-type]  # numpy stubs: ndarray.__buffer__ only on Python >= 3.12
        for i in np.nonzero(~done)[0].tolist():
            raw = bytes(view[int(offsets[i]):int(offsets[i] + sizes[i])])
            rows[i] = _message_row(canon[topic], _deserialize(reader, bag, topic, mtype, raw))
        return rows

    return read_topics(reader, conns, decode)


def _stream_names(cable_names: list[str], topics: Topics) -> dict[str, str]:
    """The streams' own names (:data:`IMU_TOPIC`, ...) by the bag's topic names (``topics``)."""
    canon = {topics.imu: IMU_TOPIC, topics.exciter: EXCITER_TOPIC, topics.inclinometer: INCLINOMETER_TOPIC}
    for name in cable_names:
        canon[topics.load_cells + name] = LOAD_CELL_PREFIX + name
    return canon


def _rig_connections(reader: AnyReader, bag: Path, canon: dict[str, str], cable_names: list[str],
                     topics: Topics) -> list[Connection]:
    """The bag's connections of the rig's streams (``canon``: the streams' own names by the bag's topic
    names).  Raises :class:`RecordingError` for a topic of the wrong type or a load-cell topic of a cable
    not in ``cable_names``."""
    wanted = {IMU_TOPIC: IMU_TYPE, EXCITER_TOPIC: WRENCH_TYPE, INCLINOMETER_TOPIC: VECTOR_TYPE}
    wanted |= {LOAD_CELL_PREFIX + name: WRENCH_TYPE for name in cable_names}
    conns = []
    for c in reader.connections:
        if c.topic in canon:
            expected = wanted[canon[c.topic]]
            if c.msgtype != expected:
                raise RecordingError(f"{bag}: topic {c.topic} has type {c.msgtype}, expected {expected}")
            conns.append(c)
        elif c.topic.startswith(topics.load_cells):
            raise RecordingError(f"{bag}: topic {c.topic} is a load cell of cable "
                                 f"{c.topic[len(topics.load_cells):]!r}, which rig.yaml does not list "
                                 f"(rig.yaml cables: {', '.join(cable_names)}); rig.yaml and the bag "
                                 "do not describe the same rig")
    return conns


@dataclass(frozen=True)
class _BagRows:
    """The rig streams' rows as read from a bag, before any check of their samples.

    names: the streams' own names by the bag's topic names.  rows: per stream (its own name),
    (N, 1 + k) rows of stamp (s) and values in write order.  found: the bag's topics as
    ``"topic (type)"``, sorted (for the error that names a missing one).
    """

    bag: Path
    names: dict[str, str]
    rows: dict[str, np.ndarray | list[tuple[float, ...]]]
    found: list[str]

    @overload
    def series(self, topic: str, required: Literal[True], warnings: list[str]) -> TimeSeries: ...

    @overload
    def series(self, topic: str, required: bool, warnings: list[str]) -> TimeSeries | None: ...

    def series(self, topic: str, required: bool, warnings: list[str]) -> TimeSeries | None:
        """Stream ``topic`` (its own name) cleaned by :func:`_time_series`; None for a missing or
        empty one, unless ``required``: then :class:`RecordingError`."""
        rows = self.rows.get(topic)
        if rows is None or not len(rows):
            if required:
                own = {v: k for k, v in self.names.items()}[topic]
                raise RecordingError(f"{self.bag}: topic {own} is missing or empty; the bag holds "
                                     f"{', '.join(self.found) or 'no topics'} (a bag recorded under other topic "
                                     "names: map them in rig.yaml topics, docs/recording_format.md)")
            return None
        return _time_series(self.bag, topic, rows, warnings)


def _read_rows(bag: Path, cable_names: list[str], bulk: bool, topics: Topics) -> _BagRows:
    """The rows of the rig's streams in ``bag`` (an existing path), read in bulk or message by
    message (:func:`read_sensor_data`'s ``bulk``).  Raises :class:`RecordingError` for an unreadable
    bag, an undecodable message, a topic of the wrong type or a load cell of an unlisted cable."""
    try:
        reader = _open_reader(bag, bulk)
        try:
            canon = _stream_names(cable_names, topics)
            found = sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections)
            conns = _rig_connections(reader, bag, canon, cable_names, topics)
            rows: Mapping[str, np.ndarray | list[tuple[float, ...]]]
            if not conns:
                rows = {}
            elif bulk and reader.is2:
                rows = _bulk_rows(reader, bag, conns, canon)
            else:
                rows = _per_message_rows(reader, bag, conns, canon)
            columns = {canon[k]: v for k, v in rows.items()}
        finally:
            reader.close()
    except RecordingError:
        raise
    except Exception as e:  # rosbags raises several exception types for broken bags
        raise RecordingError(f"{bag}: cannot read the bag ({type(e).__name__}: {e})") from None
    return _BagRows(bag, canon, columns, found)


def _drop_non_finite(bag: Path, topic: str, a: np.ndarray, warnings: list[str]) -> np.ndarray:
    """Rows ``a`` (N, 1 + k) without those holding a NaN or inf, with a warning if any."""
    finite = np.isfinite(a).all(axis=1)
    if not finite.all():
        bad = a[~finite, 0]
        warnings.append(f"{bag}: topic {topic}: {int((~finite).sum())} non-finite (NaN/inf) sample(s) "
                        f"between t={bad.min():.3f} and t={bad.max():.3f} s dropped")
        a = a[finite]
    return a


def _sort_by_stamp(bag: Path, topic: str, a: np.ndarray, warnings: list[str]) -> np.ndarray:
    """Rows ``a`` (N, 1 + k) sorted by stamp (stable), with a warning when a row was written
    :data:`QUIET_DISORDER` sampling periods or more after a later-stamped one."""
    order = np.argsort(a[:, 0], kind="stable")
    if np.any(order != np.arange(len(order))):
        late = float(np.max(np.maximum.accumulate(a[:, 0]) - a[:, 0]))
        step = np.diff(a[order, 0])
        period = float(np.median(step[step > 0])) if np.any(step > 0) else np.nan
        if not late < QUIET_DISORDER * period:
            warnings.append(f"{bag}: topic {topic}: samples out of stamp order (a sample written up to "
                            f"{late:.3g} s after a later-stamped one; sampling period {period:.3g} s); "
                            "sorted by header.stamp")
        a = a[order]
    return a


def _drop_duplicated_stamps(bag: Path, topic: str, a: np.ndarray, warnings: list[str]) -> np.ndarray:
    """Rows ``a`` (N, 1 + k, sorted by stamp) without those whose stamp repeats the previous one's
    (the first kept), with a warning if any."""
    dup = np.concatenate([[False], np.diff(a[:, 0]) <= 0])
    if dup.any():
        warnings.append(f"{bag}: topic {topic}: {int(dup.sum())} duplicated stamp(s) dropped")
        a = a[~dup]
    return a


def _time_series(bag: Path, topic: str, rows: np.ndarray | list[tuple[float, ...]],
                 warnings: list[str]) -> TimeSeries:
    """A stream from its rows (N, 1 + k: stamp s, then the values; write order): non-finite samples
    and duplicated stamps dropped, sorted by stamp, put on the stream's own rate
    (:func:`~rig_identification.io.stamps.regular_stamps`), each change with a warning appended to
    ``warnings``.  Raises :class:`RecordingError` when fewer than 2 samples remain."""
    a = _drop_non_finite(bag, topic, np.asarray(rows, float), warnings)
    a = _sort_by_stamp(bag, topic, a, warnings)
    a = _drop_duplicated_stamps(bag, topic, a, warnings)
    if len(a) < 2:
        raise RecordingError(f"{bag}: topic {topic} has fewer than 2 valid samples")
    t, note = regular_stamps(a[:, 0], topic)
    if note:
        warnings.append(f"{bag}: {note}")
    return TimeSeries(t, a[:, 1:])


def read_sensor_data(bag: Path, cable_names: list[str], warnings: list[str] | None = None,
                     bulk: bool = True, topics: Topics = Topics()) -> SensorData:
    """Read the rig topics of a rosbag2 folder (or a single .mcap/.db3 file).

    Samples are sorted by header stamp.  Non-finite samples and duplicated stamps are
    dropped with a warning appended to ``warnings``; stamps that jitter (a sensor stamped on
    arrival) are put on the stream's own rate with a warning
    (:func:`~rig_identification.io.stamps.regular_stamps`); a topic written out of stamp order by
    a sampling period or more (:data:`QUIET_DISORDER`) is sorted with a warning, a smaller
    disorder silently.  Unknown topics are ignored.  Frame ids are not checked (they are
    node parameters, docs/ros.md).

    bulk: decode the messages in bulk over their raw bytes (:mod:`rig_identification.io.bag_decode`,
    :mod:`rig_identification.io.bag_raw`), ~10-20x faster; False deserialises every message with rosbags (the
    reference the bulk path is tested to equal exactly, and its fallback).  topics: the bag's
    topic names (rig.yaml ``topics``).

    Raises :class:`RecordingError` for a missing or unreadable bag, a message that cannot be
    decoded (naming its topic), a topic of the wrong type, a load-cell topic of a cable
    rig.yaml does not list, a missing topic, or a cable in ``cable_names`` without a
    load-cell topic.
    """
    warnings = [] if warnings is None else warnings
    bag = Path(bag)
    if not bag.exists():
        raise RecordingError(f"{bag}: no bag here")
    read = _read_rows(bag, cable_names, bulk, topics)
    imu = read.series(IMU_TOPIC, True, warnings)
    cells = {n: read.series(LOAD_CELL_PREFIX + n, True, warnings) for n in cable_names}
    return SensorData(imu, cells, read.series(EXCITER_TOPIC, False, warnings),
                      read.series(INCLINOMETER_TOPIC, False, warnings))


def crop(sensors: SensorData, t0: float, t1: float) -> SensorData:
    """The sensor streams within [t0, t1] (stamps in s)."""
    @overload
    def w(s: TimeSeries) -> TimeSeries: ...

    @overload
    def w(s: TimeSeries | None) -> TimeSeries | None: ...

    def w(s: TimeSeries | None) -> TimeSeries | None:
        return None if s is None else s.window(t0, t1)
    return SensorData(w(sensors.imu), {n: w(s) for n, s in sensors.load_cells.items()},
                      w(sensors.exciter), w(sensors.inclinometer))


def on_own_clocks(sensors: SensorData, topics: Topics, warnings: list[str]) -> SensorData:
    """``sensors`` with each stream's stamps put on its own clock where they jitter
    (:func:`~rig_identification.io.stamps.regular_stamps`: a sensor stamped on arrival), a warning
    naming its topic (``topics``, rig.yaml's) appended to ``warnings`` for each stream that was:
    what the reader does to a bag's streams, for streams buffered live (the identifier node's)."""
    def own(s: TimeSeries, topic: str) -> TimeSeries:
        t, note = regular_stamps(s.t, topic)
        if note:
            warnings.append(note)
        return s if note is None else TimeSeries(t, s.data)

    return SensorData(own(sensors.imu, topics.imu),
                      {n: own(s, topics.load_cells + n) for n, s in sensors.load_cells.items()},
                      None if sensors.exciter is None else own(sensors.exciter, topics.exciter),
                      None if sensors.inclinometer is None else own(sensors.inclinometer, topics.inclinometer))


def read_recording(path: str | Path) -> Recording:
    """Read a recording folder (``rig.yaml`` + ``bag/`` [+ ``truth.yaml``]).

    Raises :class:`RecordingError` or :class:`~rig_identification.io.rig.RigError`.
    """
    p = Path(path)
    if not p.is_dir():
        raise RecordingError(f"{p}: not a recording folder")
    rig_path = p / "rig.yaml"
    if not rig_path.exists():
        raise RecordingError(f"{p}: no rig.yaml in the recording folder")
    rig = load_rig(rig_path)
    warnings: list[str] = []
    sensors = read_sensor_data(p / "bag", rig.cable_names, warnings, topics=rig.topics)
    truth = None
    if (p / "truth.yaml").exists():
        try:
            truth = yaml.safe_load((p / "truth.yaml").read_text())
        except yaml.YAMLError as e:
            raise RecordingError(f"{p / 'truth.yaml'}: not valid YAML ({e})") from None
    return Recording(rig, sensors, truth, p, warnings)


def recording_labels(recs: list[Recording]) -> list[str]:
    """Short names of the recordings: folder names, or full paths where names repeat."""
    names = [Path(r.path).name if r.path is not None else f"recording {i + 1}" for i, r in enumerate(recs)]
    return [n if names.count(n) == 1 else str(r.path) for n, r in zip(names, recs)]
