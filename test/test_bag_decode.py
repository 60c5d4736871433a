"""Bulk bag reading (bag_decode, bag_raw): the same arrays, warnings and errors as rosbags'
per-message deserialisation, on every reference recording and on hand-made bags in both
storages (frame ids of other lengths, big-endian CDR, padded and truncated messages,
non-finite samples, out-of-order and duplicated stamps, a message index that lies).
"""
import dataclasses
import shutil

import numpy as np
import pytest
from conftest import recording
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapReader
from rosbags.typesys import Stores, get_typestore

from rig_identification.io import recording as R
from rig_identification.io.bag_decode import DOUBLE_FIELDS, TYPE_HASHES, decode_stamped, payload_offset
from rig_identification.io.bag_raw import IndexMismatch, chunk_messages, read_chunk
from rig_identification.io.recording import (
    IMU_TOPIC,
    LOAD_CELL_PREFIX,
    RecordingError,
    SensorData,
    TimeSeries,
    read_sensor_data,
)
from rig_identification.io.recording_writer import sensor_messages
from rig_identification.io.rig import load_rig, rig_from_dict

REFERENCES = ["visible_case16_clean", "visible_case14_clean", "visible_case16_damped",
              "visible_case16_static/static_baseline", "visible_case16_static/static_dummy"]
TS = get_typestore(Stores.ROS2_JAZZY)
RATE = 100.0


def streams(s: SensorData):
    return [("imu", s.imu), *sorted(s.load_cells.items()), ("exciter", s.exciter), ("inclinometer", s.inclinometer)]


def assert_same(bag, cables):
    """Bulk and per-message reading of ``bag``: equal arrays (exactly) and warnings."""
    wb, wp = [], []
    bulk = read_sensor_data(bag, cables, wb, bulk=True)
    ref = read_sensor_data(bag, cables, wp, bulk=False)
    for (name, a), (_, b) in zip(streams(bulk), streams(ref)):
        assert (a is None) == (b is None), name
        if a is not None:
            assert np.array_equal(a.t, b.t) and np.array_equal(a.data, b.data), name
            assert a.data.shape == b.data.shape, name
    assert wb == wp
    return bulk, wb


# --- the CDR layout -------------------------------------------------------------------------

def _message(msgtype, frame_id, sec, nanosec, v):
    """A message of ``msgtype`` whose float64 fields (DOUBLE_FIELDS order) are ``v``."""
    T = TS.types
    vec = lambda a: T["geometry_msgs/msg/Vector3"](x=a[0], y=a[1], z=a[2])  # noqa: E731
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                      frame_id=frame_id)
    if msgtype == "sensor_msgs/msg/Imu":
        return T[msgtype](header=header, orientation=T["geometry_msgs/msg/Quaternion"](x=v[0], y=v[1], z=v[2], w=v[3]),
                          orientation_covariance=v[4:13], angular_velocity=vec(v[13:16]),
                          angular_velocity_covariance=v[16:25], linear_acceleration=vec(v[25:28]),
                          linear_acceleration_covariance=v[28:37])
    if msgtype == "geometry_msgs/msg/WrenchStamped":
        return T[msgtype](header=header, wrench=T["geometry_msgs/msg/Wrench"](force=vec(v[:3]), torque=vec(v[3:])))
    return T[msgtype](header=header, vector=vec(v))


def _field(msg, path):
    for part in path.replace("[", ".").replace("]", "").split("."):
        msg = msg[int(part)] if part.isdigit() else getattr(msg, part)
    return msg


def _pack(raws):
    buf = b"".join(raws)
    sizes = np.array([len(r) for r in raws])
    return np.frombuffer(buf, np.uint8), np.cumsum(sizes) - sizes, sizes


@pytest.mark.parametrize("msgtype", sorted(DOUBLE_FIELDS))
def test_layout_is_rosbags_serialisation(msgtype):
    """Every float64 field and the stamp, for frame ids of every length mod 8 (every padding),
    decoded in bulk from one buffer equal rosbags' per-message deserialisation."""
    names = DOUBLE_FIELDS[msgtype]
    rng = np.random.default_rng(1)
    raws, values, stamps = [], [], []
    for k in range(18):
        v = rng.standard_normal(len(names)) * 10.0 ** rng.integers(-9, 9, len(names))
        sec, nsec = int(rng.integers(-2**31, 2**31)), int(rng.integers(0, 10**9))
        raw = bytes(TS.serialize_cdr(_message(msgtype, "f" * k, sec, nsec, v), msgtype))
        assert len(raw) == payload_offset(k + 1) + 8 * len(names)
        msg = TS.deserialize_cdr(raw, msgtype)
        raws.append(raw)
        values.append([_field(msg, f) for f in names])
        stamps.append(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)
    rows, decoded = decode_stamped(*_pack(raws), msgtype, names)
    assert decoded.all()
    assert np.array_equal(rows[:, 0], stamps) and np.array_equal(rows[:, 1:], values)
    picked = decode_stamped(*_pack(raws), msgtype, names[::-3]).rows
    assert np.array_equal(picked[:, 1:], np.array(values)[:, ::-1][:, ::3])


def test_unusual_messages_are_left_to_rosbags():
    """Big-endian CDR, padding after the message, a frame id without its NUL or not UTF-8, a
    truncated message: not decoded in bulk (the caller deserialises them); the rest are."""
    mtype = "geometry_msgs/msg/Vector3Stamped"
    good = bytes(TS.serialize_cdr(_message(mtype, "inclinometer", 7, 9, [1.0, 2.0, 3.0]), mtype))
    big = bytes(TS.serialize_cdr(_message(mtype, "inclinometer", 7, 9, [1.0, 2.0, 3.0]), mtype, little_endian=False))
    no_nul = good[:16 + 12] + b"x" + good[16 + 13:]
    latin = good[:16] + "inclinometeré".encode("latin-1") + good[16 + 13:]
    raws = [good, big, good + b"\0\0\0", no_nul, latin, good[:30], good]
    rows, decoded = decode_stamped(*_pack(raws), mtype, ["vector.x", "vector.y"])
    assert decoded.tolist() == [True, False, False, False, False, False, True]
    assert np.array_equal(rows[decoded], [[7 + 9e-9, 1.0, 2.0]] * 2)
    assert np.isnan(rows[~decoded]).all()


def test_type_hashes_are_the_jazzy_definitions():
    assert TYPE_HASHES == {t: TS.hash_rihs01(t) for t in DOUBLE_FIELDS}


# --- whole recordings ------------------------------------------------------------------------

@pytest.mark.parametrize("name", REFERENCES)
def test_reference_recordings_read_identically(name):
    rec = recording(name)
    assert_same(rec / "bag", load_rig(rec / "rig.yaml").cable_names)


@pytest.fixture(scope="module")
def rig():
    return load_rig(recording("visible_case16_clean") / "rig.yaml")


def synthetic(rig, n=300):
    """Noise streams at RATE, stamps near 1.75e9 s (float64 resolution 2.4e-7 s), with a
    NaN in the IMU and an inf in a load cell."""
    rng = np.random.default_rng(0)
    t = 1.75e9 + np.arange(n) / RATE
    imu = TimeSeries(t, rng.standard_normal((n, 6)))
    imu.data[40, 2] = np.nan
    cells = {c: TimeSeries(t + 3e-4, rng.normal(5000.0, 10.0, (n, 1))) for c in rig.cable_names}
    cells[rig.cable_names[1]].data[77, 0] = np.inf
    return SensorData(imu, cells, TimeSeries(t, rng.standard_normal((n, 2))),
                      TimeSeries(t[::4], 0.01 * rng.standard_normal((n // 4, 2))))


def write(path, rig, items, storage):
    """A recording folder: rig.yaml and a bag of ``items`` (topic, msgtype, log time ns,
    serialized message), written in that order."""
    path.mkdir()
    shutil.copy(recording("visible_case16_clean") / "rig.yaml", path / "rig.yaml")
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    with Writer(path / "bag", version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, mtype, t_ns, raw in items:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, mtype, typestore=TS)
            w.write(conns[topic], t_ns, raw)
    return path / "bag"


def serialized(rig, sensors, edit=None):
    """(topic, msgtype, log time ns, CDR) for every sample; ``edit(i, topic, msg)`` may
    return a replacement message or raw bytes for the i-th message of its topic."""
    count: dict[str, int] = {}
    out = []
    for topic, mtype, t, msg in sensor_messages(rig, sensors):
        i = count[topic] = count.get(topic, -1) + 1
        new = edit(i, topic, msg) if edit else None
        raw = new if isinstance(new, bytes) else bytes(TS.serialize_cdr(new or msg, mtype))
        out.append((topic, mtype, int(round(t * 1e9)), raw))
    return out


def _frame(msg, frame_id):
    return dataclasses.replace(msg, header=dataclasses.replace(msg.header, frame_id=frame_id))


def odd(i, topic, msg):
    """Frame ids of other lengths (varying within /rig/imu, another one for the whole exciter
    topic), big-endian CDR and trailing padding on some IMU messages."""
    if topic == IMU_TOPIC:
        if i % 7 == 3:
            return _frame(msg, "imu_link_of_another_length")
        if i % 11 == 5:
            return bytes(TS.serialize_cdr(msg, "sensor_msgs/msg/Imu", little_endian=False))
        if i % 13 == 6:
            return bytes(TS.serialize_cdr(msg, "sensor_msgs/msg/Imu")) + b"\0\0"
    if topic == R.EXCITER_TOPIC:
        return _frame(msg, "exciter_frame")
    return None


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_odd_bags_read_identically(rig, tmp_path, storage):
    bag = write(tmp_path / "rec", rig, serialized(rig, synthetic(rig), odd), storage)
    sensors, warnings = assert_same(bag, rig.cable_names)
    assert len(sensors.imu) == 299 and np.isfinite(sensors.imu.data).all()
    assert any(IMU_TOPIC in w and "non-finite" in w for w in warnings)
    assert any(LOAD_CELL_PREFIX + rig.cable_names[1] in w and "non-finite" in w for w in warnings)
    # every message really went through the bulk decoder or the fallback, and arrived
    assert len(sensors.exciter) == 300 and len(sensors.inclinometer) == 75


def test_single_file_and_nonstandard_definition(rig, tmp_path, monkeypatch):
    """A bare .mcap file reads the same; a type whose definition in the bag is not the
    standard one (here: the expected hash altered) is deserialised message by message."""
    bag = write(tmp_path / "rec", rig, serialized(rig, synthetic(rig), odd), "mcap")
    assert_same(next(bag.glob("*.mcap")), rig.cable_names)
    monkeypatch.setitem(R.TYPE_HASHES, "sensor_msgs/msg/Imu", "RIHS01_" + "0" * 64)
    assert_same(bag, rig.cable_names)


def test_lying_message_index_falls_back(rig, tmp_path):
    """A message index entry pointing at a record of another channel: the MCAP fast path
    refuses the chunk (IndexMismatch) and the bag is read by iteration, identically."""
    bag = write(tmp_path / "rec", rig, serialized(rig, synthetic(rig)), "mcap")
    f = next(bag.glob("*.mcap"))

    def first_chunk():
        r = McapReader(f)
        r.open()
        try:
            return r.chunks[0]
        finally:
            r.close()
    chunk = first_chunk()
    data = bytearray(f.read_bytes())
    entries = [p + 1 + 8 + 2 + 4 for p in chunk.message_index_offsets.values()]  # after op, length, channel, size
    data[entries[0] + 8:entries[0] + 16] = data[entries[1] + 8:entries[1] + 16]   # offset of another channel's
    f.write_bytes(bytes(data))
    with open(f, "rb") as fh:
        records, index = read_chunk(fh, chunk)
    with pytest.raises(IndexMismatch):
        chunk_messages(records, chunk, index)
    assert_same(bag, rig.cable_names)


def test_undecodable_message_names_its_topic(rig, tmp_path):
    cut = lambda i, topic, msg: (bytes(TS.serialize_cdr(msg, "sensor_msgs/msg/Imu"))[:40]  # noqa: E731
                                 if topic == IMU_TOPIC and i == 9 else None)
    bag = write(tmp_path / "rec", rig, serialized(rig, synthetic(rig), cut), "mcap")
    errors = []
    for bulk in (True, False):
        with pytest.raises(RecordingError) as e:
            read_sensor_data(bag, rig.cable_names, [], bulk=bulk)
        errors.append(str(e.value))
    assert errors[0] == errors[1] and f"topic {IMU_TOPIC}: cannot decode" in errors[0]


# --- stamp order -------------------------------------------------------------------------------

def _restamp(sensors, stream, stamps):
    return dataclasses.replace(sensors, **{stream: TimeSeries(stamps, getattr(sensors, stream).data)})


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_disorder_below_a_period_is_silent(rig, tmp_path, storage):
    """Write order vs stamp order: 0.3 period late on the IMU (an extra sample between two
    grid points, written after the later one) is sorted silently; a swap of two neighbours
    of the exciter (one period) and a duplicated stamp on the inclinometer warn."""
    s = synthetic(rig)
    s.imu.data[40, 2] = 0.0
    t = s.imu.t.copy()
    t[101] = t[100] + 0.3 / RATE      # off the grid; written swapped below: stamps 100, 100.6, 100.3, 103
    t[102] = t[100] + 0.6 / RATE
    s = _restamp(s, "imu", t)
    items = serialized(rig, s)

    def log_time_order(items):  # keep the header stamps, write every message at its grid time
        out, k = [], {}
        for topic, mtype, _, raw in items:
            i = k[topic] = k.get(topic, -1) + 1
            out.append((topic, mtype, 1_750_000_000_000_000_000 + int(i * 1e9 / RATE * (4 if "incl" in topic else 1)),
                        raw))
        return out
    items = log_time_order(items)
    def swap(topic, i):   # the payloads of a topic's messages i and i + 1 (bag times stay in order)
        a, b = [j for j, it in enumerate(items) if it[0] == topic][i:i + 2]
        items[a], items[b] = items[a][:3] + items[b][3:], items[b][:3] + items[a][3:]
    swap(IMU_TOPIC, 101)
    swap(R.EXCITER_TOPIC, 50)
    inc = [j for j, it in enumerate(items) if it[0] == R.INCLINOMETER_TOPIC]
    items[inc[20]] = items[inc[20]][:3] + items[inc[19]][3:]
    bag = write(tmp_path / "rec", rig, items, storage)
    sensors, warnings = assert_same(bag, rig.cable_names)
    assert not [w for w in warnings if IMU_TOPIC in w], warnings
    assert np.all(np.diff(sensors.imu.t) > 0) and len(sensors.imu) == 300
    assert any(R.EXCITER_TOPIC in w and "out of stamp order" in w for w in warnings), warnings
    assert any(R.INCLINOMETER_TOPIC in w and "duplicated" in w for w in warnings), warnings
    assert not [w for w in warnings if R.INCLINOMETER_TOPIC in w and "out of stamp order" in w], warnings


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_write_order_is_rosbags_order(rig, tmp_path, storage):
    """Messages written out of bag-time order across two MCAP chunks with overlapping time
    ranges, IMU pairs with one bag time and one header stamp but different values: the
    sample that survives the duplicate is the one rosbags yields first (bag time, chunk,
    position in the chunk; sqlite3: its query's order)."""
    s = synthetic(rig, 1500)
    s.imu.data[40, 2] = 0.0
    items, imu, twins = [], 0, 0
    for topic, mtype, t, raw in serialized(rig, s):
        items.append((topic, mtype, t // 2_000_000 * 2_000_000, raw))   # bag times on a 2 ms grid: ties
        imu += topic == IMU_TOPIC
        if topic == IMU_TOPIC and imu % 10 == 0:   # a twin every 10th IMU sample, same bag time or 1 ms later
            msg = TS.deserialize_cdr(raw, mtype)
            twin = dataclasses.replace(msg, angular_velocity=dataclasses.replace(
                msg.angular_velocity, x=msg.angular_velocity.x + 1.0))
            items.append((topic, mtype, items[-1][2] + twins % 2 * 1_000_000, bytes(TS.serialize_cdr(twin, mtype))))
            twins += 1
    rng = np.random.default_rng(3)
    order = np.arange(len(items))
    for w in range(0, len(items) - 39, 40):   # shuffled within windows of 40 messages
        order[w:w + 40] = w + rng.permutation(40)
    bag = write(tmp_path / "rec", rig, [items[i] for i in order], storage)
    if storage == "mcap":
        r = McapReader(next(bag.glob("*.mcap")))
        r.open()
        assert len(r.chunks) >= 2
        r.close()
    sensors, warnings = assert_same(bag, rig.cable_names)
    assert any(IMU_TOPIC in w and f"{twins} duplicated" in w for w in warnings), warnings


# --- the lab's own topic names ---------------------------------------------------------------

@pytest.mark.parametrize("bulk", [True, False])
def test_lab_topic_names_map_through_rig_yaml(rig, tmp_path, bulk):
    """A bag recorded under the lab's own topic names: without rig.yaml ``topics`` the error
    names the missing stream and lists what the bag holds; with them the streams read exactly
    as under the standard names."""
    own = {IMU_TOPIC: "/hall3/imu/data", R.EXCITER_TOPIC: "/hall3/shaker/force",
           R.INCLINOMETER_TOPIC: "/hall3/tilt"}
    rename = lambda topic: own.get(topic, topic.replace(LOAD_CELL_PREFIX, "/hall3/cells/"))  # noqa: E731
    items = serialized(rig, synthetic(rig))
    bag = write(tmp_path / "lab", rig, [(rename(t), m, ns, raw) for t, m, ns, raw in items], "mcap")
    with pytest.raises(RecordingError) as e:
        read_sensor_data(bag, rig.cable_names, [], bulk=bulk)
    msg = str(e.value)
    assert f"topic {IMU_TOPIC} is missing or empty" in msg
    assert "/hall3/imu/data (sensor_msgs/msg/Imu)" in msg and "/hall3/cells/c0 (geometry_msgs/msg/WrenchStamped)" in msg
    d = rig.to_dict() | {"topics": {"imu": "/hall3/imu/data", "load_cells": "/hall3/cells/",
                                    "exciter": "/hall3/shaker/force", "inclinometer": "/hall3/tilt"}}
    mapped = rig_from_dict(d, "rig.yaml")
    assert rig_from_dict(mapped.to_dict()).topics == mapped.topics          # written back as read
    got = read_sensor_data(bag, rig.cable_names, [], bulk=bulk, topics=mapped.topics)
    ref = read_sensor_data(write(tmp_path / "std", rig, items, "mcap"), rig.cable_names, [], bulk=bulk)
    np.testing.assert_array_equal(got.imu.data, ref.imu.data)
    np.testing.assert_array_equal(got.exciter.t, ref.exciter.t)
    for n in rig.cable_names:
        np.testing.assert_array_equal(got.load_cells[n].data, ref.load_cells[n].data)
    np.testing.assert_array_equal(got.inclinometer.data, ref.inclinometer.data)


def test_topic_name_field_is_checked(rig):
    with pytest.raises(Exception, match="topics.imu must be a ROS topic name"):
        rig_from_dict(rig.to_dict() | {"topics": {"imu": "rig imu"}}, "rig.yaml")
    with pytest.raises(Exception, match="unknown field topics.gyro"):
        rig_from_dict(rig.to_dict() | {"topics": {"gyro": "/a"}}, "rig.yaml")
