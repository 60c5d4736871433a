"""The node graph as separate processes over DDS (a private ROS_DOMAIN_ID, localhost only).

One replay serves every test of this module (fixture ``graph``): 30 s of the default
experiment are simulated here (so that the true motion is known), written as a recording,
and replayed by sensor_driver at 3x real time to tracker, preprocessor and identifier.
This process listens to every topic.  The identifier fits the last ``WINDOW`` s (its
``window_last``) and runs with ``debug_fit_delay`` so that a fit lasts long enough to be
interrupted by a second request; one answer (fixture ``answer``) serves the tests that read it.
"""
from __future__ import annotations

import json
import math
import random
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

rclpy = pytest.importorskip("rclpy")

from ros_helpers import Listener, wait_until  # noqa: E402

from rig_identification.estimation.tracker import PoseTracker  # noqa: E402
from rig_identification.io.recording import Recording, crop, read_recording  # noqa: E402
from rig_identification.io.recording_writer import write_recording  # noqa: E402
from rig_identification.model.experiment import load_experiment  # noqa: E402
from rig_identification.model.simulator import simulate  # noqa: E402
from rig_identification.nodes.demo import Graph  # noqa: E402
from rig_identification.nodes.environment import ros_env  # noqa: E402
from rig_identification.nodes.merge import StampMerger  # noqa: E402
from rig_identification.nodes.messages import set_stamp, stamp_to_sec  # noqa: E402
from rig_identification.nodes.qos import LATCHED_QOS, SENSOR_QOS  # noqa: E402
from rig_identification.nodes.topics import (  # noqa: E402
    EXCITER_TOPIC,
    IMU_TOPIC,
    INCLINOMETER_TOPIC,
    LOAD_CELL_PREFIX,
    MASS_PROPERTIES_TOPIC,
    POSE_TOPIC,
    WRENCH_TOPIC,
)
from rig_identification.pipeline.rig_model import fit_whole_recording  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DURATION = 30.0
RATE = 3.0
FIT_DELAY = 2.0
WINDOW = 15.0
KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


@pytest.fixture(scope="module")
def sim():
    exp = load_experiment(REPO / "config" / "rigs" / "default.yaml").with_overrides(duration=DURATION)
    return simulate(exp)


@pytest.fixture(scope="module")
def graph(sim, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("graph")
    rec = write_recording(tmp / "recording", sim.rig, sim.sensors, sim.truth)
    g = Graph(workdir=tmp / "nodes", domain_id=random.Random().randint(100, 199))
    rig = str(rec / "rig.yaml")
    listener = Listener(g.domain_id, sim.rig.cable_names)
    try:
        g.start("sensor_driver", {"recording": str(rec), "rate": RATE, "start_delay": 1.0, "wait_timeout": 60.0,
                                  "wait_for": ["/rig/imu:3", "/rig/load_cells/*:3", "/rig/exciter/wrench:3",
                                               "/rig/inclinometer:2", "/rig/pose:2", "/rig/generalized_wrench:1"]})
        g.start("tracker", {"rig": rig})
        g.start("preprocessor", {"rig": rig})
        g.start("identifier", {"rig": rig, "debug_fit_delay": FIT_DELAY, "min_duration": 10.0,
                               "window_last": WINDOW})
        state = lambda: (f"driver status {listener.status}\nlistener counts {listener.counts}\n"  # noqa: E731
                         f"diagnostics {listener.diag}")
        wait_until(lambda: listener.status.get("state") == "done", 120.0, "the driver to finish", g, info=state)
        total = listener.status["total"]

        def drained():
            d, c = listener.diag, listener.counts
            wrenches = d.get("/preprocessor", {}).get("tx /rig/generalized_wrench", -1)
            poses = d.get("/tracker", {}).get("tx /rig/pose", -1)
            return (d.get("/identifier", {}).get("rx /rig/imu") == total[IMU_TOPIC]
                    and d.get("/tracker", {}).get("rx /rig/imu") == total[IMU_TOPIC]
                    and c.get(WRENCH_TOPIC) == wrenches and c.get(POSE_TOPIC) == poses
                    and all(c.get(t) == n for t, n in total.items()))
        # every node (and this listener) has processed everything
        wait_until(drained, 120.0, "the pipeline to drain", g, info=state)
        time.sleep(1.0)
        yield g, listener, sim, rec
    finally:
        listener.close()
        codes = g.stop()
        print("exit codes:", codes)


def test_every_topic_arrives_without_drops(graph):
    g, lis, sim, rec = graph
    total = lis.status["total"]
    s = sim.sensors
    expected = {IMU_TOPIC: len(s.imu), EXCITER_TOPIC: len(s.exciter),
                INCLINOMETER_TOPIC: len(s.inclinometer)}
    expected.update({LOAD_CELL_PREFIX + n: len(v) for n, v in s.load_cells.items()})
    assert total == expected
    assert lis.status["published"] == expected
    for topic, n in expected.items():
        assert lis.counts.get(topic) == n, f"{topic}: listener got {lis.counts.get(topic)} of {n}"
    # each node received every message it subscribes to, none rejected
    for node, topics in {"/tracker": list(expected), "/preprocessor": [t for t in expected if t != IMU_TOPIC
                                                                       and t != INCLINOMETER_TOPIC],
                         "/identifier": list(expected)}.items():
        d = lis.diag[node]
        for topic in topics:
            assert d[f"rx {topic}"] == expected[topic], (node, topic, d)
            assert d[f"rejected {topic}"] == 0, (node, topic, d)
    # derived streams: one pose per IMU sample after the tracker's initialisation, no loss downstream
    poses_tx = lis.diag["/tracker"]["tx /rig/pose"]
    assert expected[IMU_TOPIC] - 25 <= poses_tx < expected[IMU_TOPIC]
    assert lis.counts[POSE_TOPIC] == poses_tx
    assert lis.diag["/preprocessor"]["rx /rig/pose"] == poses_tx
    wrench_tx = lis.diag["/preprocessor"]["tx /rig/generalized_wrench"]
    assert wrench_tx >= poses_tx - 5
    assert lis.counts[WRENCH_TOPIC] == wrench_tx
    # frames of RECORDING_FORMAT.md
    assert lis.frames[IMU_TOPIC] == {"imu"}
    assert lis.frames[EXCITER_TOPIC] == {"exciter"}
    assert lis.frames[INCLINOMETER_TOPIC] == {"inclinometer"}
    assert lis.frames[LOAD_CELL_PREFIX + "c0"] == {"load_cell_c0"}
    assert lis.frames[WRENCH_TOPIC] == {"body"}
    assert lis.frames[POSE_TOPIC] == {("world", "body")}


def test_pose_matches_simulated_truth(graph):
    g, lis, sim, rec = graph
    with lis.lock:
        P = np.array(lis.poses)
    st = sim.states
    idx = np.searchsorted(st.t, P[:, 0] - 1e-6)
    assert np.allclose(st.t[idx], P[:, 0], atol=1e-6), "pose stamps are not the IMU stamps"
    late = P[:, 0] - st.t[0] > 5.0  # the complementary filters have converged
    dp = P[:, 1:4] - st.position[idx]
    R_true = Rotation.from_quat(st.quaternion[idx])
    R_est = Rotation.from_quat(P[:, 4:8])
    dr = (R_true.inv() * R_est).magnitude()
    print(f"pose errors after 5 s: position {np.abs(dp[late]).max():.2e} m, orientation {dr[late].max():.2e} rad, "
          f"omega {np.abs(P[late, 8:11] - st.omega[idx][late]).max():.2e} rad/s, "
          f"velocity {np.abs(P[late, 11:14] - R_true.inv().apply(st.velocity[idx])[late]).max():.2e} m/s")
    assert np.abs(dp[late]).max() < 5e-3, np.abs(dp[late]).max(0)
    assert dr[late].max() < 2e-3, dr[late].max()
    # twist: angular = body rates (the gyro, noise 0.002 rad/s); linear = body-axes velocity
    assert np.abs(P[late, 8:11] - st.omega[idx][late]).max() < 0.015  # ~7 sigma of the gyro noise
    v_body_true = R_true.inv().apply(st.velocity[idx])
    assert np.abs(P[late, 11:14] - v_body_true[late]).max() < 0.01
    # the body really moved: the comparison is not trivial
    assert np.ptp(st.position[idx][late], axis=0).max() > 5e-3


@pytest.fixture(scope="module")
def answer(graph):
    """~/identify_rig_model's answer on the replayed recording: the parsed JSON."""
    g, lis, sim, rec = graph
    r = lis.call("/identifier/identify_rig_model")
    assert r.success, r.message
    return json.loads(r.message)


def test_identify_service_answers_the_rig_model_over_the_window(graph, answer):
    """~/identify_rig_model fits the last window_last s of the raw streams: verdict ok, the
    moments within 1 % of the truth and 3 σ, the mass and CG fitted, the window in s after the
    first IMU sample, every sample received."""
    g, lis, sim, rec = graph
    d = answer
    for key in ("verdict", "mass", "center_of_gravity", "inertia_about_cg", "inertia_std", "inertia_crb", "window",
                "received", "residual_level", "diagnosis"):
        assert key in d, key
    assert d["verdict"] == "ok", d["verdict"]
    truth = sim.truth["inertia_about_cg"]
    for k in KEYS:
        err = d["inertia_about_cg"][k] - truth[k]
        assert abs(err) < 3 * d["inertia_std"][k], (k, err, d["inertia_std"][k])
        if k in ("ixx", "iyy", "izz"):
            assert abs(err) < 0.01 * truth[k], (k, err)
    assert d["mass"] == pytest.approx(sim.truth["mass"], rel=2e-3)
    w = d["window"]
    t_first, t_last = float(sim.sensors.imu.t[0]), float(sim.sensors.imu.t[-1])
    assert w["end_relative"] == pytest.approx(t_last - t_first, abs=1e-6)
    assert w["end_relative"] - w["start_relative"] == pytest.approx(WINDOW, abs=0.01)   # the samples in it
    assert w["start_stamp"] == pytest.approx(t_first + w["start_relative"], abs=1e-6)
    assert d["received"]["imu"] == lis.status["total"][IMU_TOPIC]
    assert d["received"]["load_cells"] == sum(n for t, n in lis.status["total"].items()
                                              if t.startswith(LOAD_CELL_PREFIX))


def test_the_node_answers_what_the_core_fits_to_the_same_window(graph, answer):
    """The node runs the core of ``rig-identify inertia`` on the samples it received: the
    recording cropped to the node's window and fitted here gives the same tensor, mass and CG
    (DDS carries every sample unchanged)."""
    g, lis, sim, rec = graph
    offline = read_recording(rec)
    w = answer["window"]
    cropped = Recording(offline.rig, crop(offline.sensors, w["start_stamp"], w["end_stamp"]), None, rec)
    ref = fit_whole_recording(cropped).to_dict()
    for k in KEYS:
        assert answer["inertia_about_cg"][k] == pytest.approx(ref["inertia_about_cg"][k], rel=1e-9), k
    assert answer["mass"] == pytest.approx(ref["mass"], rel=1e-12)
    assert answer["verdict"] == ref["verdict"]


def test_the_tracker_node_reproduces_the_core_fed_in_stamp_order(graph):
    """Arrival order over DDS differs from stamp order; the tracker node merges its inputs by
    stamp, so its poses are those of the tracker core fed in stamp order in one process (ties
    as tracker_replay.track: inclinometer, tensions, IMU, exciter)."""
    g, lis, sim, rec = graph
    rig, sensors = sim.rig, sim.sensors
    tr = PoseTracker(rig)
    names = rig.cable_names
    ev = [(t, 2, 0, i) for i, t in enumerate(sensors.imu.t)]
    ev += [(t, 1, k, i) for k, n in enumerate(names) for i, t in enumerate(sensors.load_cells[n].t)]
    ev += [(t, 3, 0, i) for i, t in enumerate(sensors.exciter.t)]
    ev += [(t, 0, 0, i) for i, t in enumerate(sensors.inclinometer.t)]
    ev.sort()
    group, poses = {}, []
    for t, kind, k, i in ev:
        if kind == 2:
            pose = tr.add_imu(t, sensors.imu.data[i, :3], sensors.imu.data[i, 3:])
            if pose is not None:
                poses.append(np.r_[pose.t, pose.position, pose.quaternion])
        elif kind == 1:
            group[names[k]] = float(sensors.load_cells[names[k]].data[i, 0])
            if len(group) == len(names):
                tr.add_tensions(t, group)
                group = {}
        elif kind == 3:
            if not tr.initialised:
                tr.add_exciter(t, sensors.exciter.data[i])
        else:
            tr.add_inclinometer(t, sensors.inclinometer.data[i])
    core = np.array(poses)
    with lis.lock:
        node = np.array(lis.poses)[:, :8]
    assert node.shape == core.shape
    assert np.allclose(node[:, 0], core[:, 0], rtol=0, atol=1e-9)
    assert np.abs(node[:, 1:4] - core[:, 1:4]).max() < 1e-9
    # the same rotation (a quaternion and its negative are one)
    assert np.abs(np.abs(np.einsum("ij,ij->i", node[:, 4:8], core[:, 4:8])) - 1).max() < 1e-9


def test_mass_properties_latched_for_a_late_subscriber(graph, answer):
    g, lis, sim, rec = graph
    d = answer
    got = []
    sub = lis.node.create_subscription(lis.InertiaStamped, MASS_PROPERTIES_TOPIC, got.append,
                                       LATCHED_QOS)
    try:
        wait_until(lambda: got, 10.0, "the latched /rig/mass_properties")
    finally:
        lis.node.destroy_subscription(sub)
    m = got[-1]
    assert m.header.frame_id == "body"
    assert m.inertia.m == pytest.approx(d["mass"])
    assert [m.inertia.com.x, m.inertia.com.y, m.inertia.com.z] == pytest.approx(d["center_of_gravity"]["combined"])
    for k in KEYS:
        assert getattr(m.inertia, k) == pytest.approx(d["inertia_about_cg"][k]), k
    assert stamp_to_sec(m.header.stamp) == pytest.approx(d["window"]["end_stamp"], abs=1e-6)


def test_second_call_during_a_fit_is_answered_busy(graph):
    g, lis, sim, rec = graph
    out = {}
    t0 = time.monotonic()
    first = threading.Thread(target=lambda: out.setdefault("first", lis.call("/identifier/identify_rig_model")))
    first.start()
    time.sleep(0.7)  # the first fit is running (it lasts FIT_DELAY s longer than the fit)
    n_diag = len(lis.diag_times.get("/identifier", []))
    t1 = time.monotonic()
    second = lis.call("/identifier/identify_rig_model", timeout=FIT_DELAY)
    answered = time.monotonic() - t1
    assert not second.success
    assert "busy" in json.loads(second.message)["error"]
    assert answered < FIT_DELAY * 0.75, f"the busy answer took {answered:.2f} s"
    status = json.loads(lis.call("/identifier/status").message)
    assert status["busy"] is True
    first.join(timeout=60)
    assert out["first"].success, out["first"].message
    assert time.monotonic() - t0 >= FIT_DELAY
    # the node's main executor kept running during the fit (its 1 Hz diagnostics went on)
    assert len(lis.diag_times["/identifier"]) > n_diag


def test_estimate_cg_asks_for_the_static_states_first(graph):
    g, lis, sim, rec = graph
    r = lis.call("/identifier/estimate_cg")
    assert not r.success
    assert "capture the baseline and dummy" in json.loads(r.message)["error"]


def test_client_prints_the_table_with_truth(graph):
    g, lis, sim, rec = graph
    p = subprocess.run([sys.executable, "-m", "rig_identification.nodes.client", "--timeout", "20"],
                       env=g.env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stdout + p.stderr
    out = p.stdout
    for word in ("verdict: ok", "the NEGATED products", "Ixx", "Iyz", "Izz", "mass", "truth", "error", "CRB",
                 "vehicle-dynamics sign", "residual over the noise"):
        assert word in out, (word, out)
    row = next(line for line in out.splitlines() if line.startswith("Ixx"))
    assert f"{sim.truth['inertia_about_cg']['ixx']:.2f}" in row


def test_client_reports_a_missing_identifier(graph):
    g, lis, sim, rec = graph
    p = subprocess.run([sys.executable, "-m", "rig_identification.nodes.client", "--identifier", "/nobody",
                        "--timeout", "1"], env=g.env, capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert "/nobody/identify_rig_model not available" in p.stderr


def test_malformed_messages_are_dropped_and_nodes_survive(graph):
    from geometry_msgs.msg import WrenchStamped
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu
    g, lis, sim, rec = graph
    node = lis.node
    before = {n: dict(lis.diag[n]) for n in ("/tracker", "/preprocessor", "/identifier")}
    t_last = float(sim.sensors.imu.t[-1])
    pubs = {t: node.create_publisher(m, t, SENSOR_QOS) for t, m in
            ((IMU_TOPIC, Imu), (POSE_TOPIC, Odometry), (LOAD_CELL_PREFIX + "c0", WrenchStamped))}
    wait_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs.values()), 10.0, "test publishers to match")

    def imu(t, frame="imu", gx=0.0):
        m = Imu()
        set_stamp(m.header, t, frame)
        m.angular_velocity.x = gx
        m.linear_acceleration.z = 9.8
        m.orientation_covariance[0] = -1.0
        return m
    pubs[IMU_TOPIC].publish(imu(t_last + 1.0, gx=math.nan))         # NaN
    pubs[IMU_TOPIC].publish(imu(t_last + 1.0, frame="camera"))      # wrong frame
    pubs[IMU_TOPIC].publish(imu(t_last - 10.0))                     # stamp going backwards
    o = Odometry()
    set_stamp(o.header, t_last + 1.0, "world")
    o.child_frame_id = "base_link"
    o.pose.pose.orientation.w = 1.0
    pubs[POSE_TOPIC].publish(o)                                     # wrong child frame
    c = WrenchStamped()
    set_stamp(c.header, t_last - 5.0, "load_cell_c0")
    pubs[LOAD_CELL_PREFIX + "c0"].publish(c)                        # stamp going backwards
    c = WrenchStamped()
    set_stamp(c.header, t_last + 1.0, "load_cell_c0")
    c.wrench.force.z = math.inf
    pubs[LOAD_CELL_PREFIX + "c0"].publish(c)                        # inf tension

    def rejected(node_name, topic):
        return lis.diag[node_name].get(f"rejected {topic}", 0) - before[node_name].get(f"rejected {topic}", 0)
    wait_until(lambda: rejected("/tracker", IMU_TOPIC) == 3
               and rejected("/identifier", IMU_TOPIC) == 3
               and rejected("/identifier", LOAD_CELL_PREFIX + "c0") == 2
               and rejected("/preprocessor", POSE_TOPIC) == 1
               and rejected("/preprocessor", LOAD_CELL_PREFIX + "c0") == 2
               and rejected("/tracker", LOAD_CELL_PREFIX + "c0") == 2, 15.0, "the rejections", g)
    assert not g.dead()
    assert "dropped a malformed message on /rig/imu" in g.log("tracker")
    # still serving, with the same data as before
    r = lis.call("/identifier/status")
    assert r.success, r.message
    status = json.loads(r.message)
    assert status["imu"] == lis.status["total"][IMU_TOPIC]
    assert status["load_cells"] == sum(n for t, n in lis.status["total"].items() if t.startswith(LOAD_CELL_PREFIX))
    for p in pubs.values():
        node.destroy_publisher(p)


def test_nodes_stop_cleanly_on_sigint(graph):
    g, lis, sim, rec = graph
    codes = g.stop(grace=10.0)
    assert codes == {"sensor_driver": 0, "tracker": 0, "preprocessor": 0, "identifier": 0}, codes


def test_nodes_refuse_a_bad_rig_description(tmp_path):
    bad = tmp_path / "rig.yaml"
    bad.write_text(yaml.safe_dump({"gravity": 9.81, "cables": []}))
    for module in ("tracker_node", "preprocessor_node", "identifier_node"):
        p = subprocess.run([sys.executable, "-m", f"rig_identification.nodes.{module}", "--ros-args",
                            "-p", f"rig:={bad}"], env=ros_env(random.Random().randint(200, 230)),
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 2, (module, p.stderr)
        assert "cables" in p.stderr and "Traceback" not in p.stderr, (module, p.stderr)


def test_stamp_merger_orders_streams_and_does_not_wait_for_a_silent_one():
    m = StampMerger(["a", "b"], max_delay=1.0)
    assert m.push("a", 1.0, 2, "a1") == []          # b has said nothing yet
    assert m.push("a", 1.1, 2, "a2") == []
    out = m.push("b", 1.05, 1, "b1")                # b reached 1.05: a1 and b1 can go
    assert [e[4] for e in out] == ["a1", "b1"]
    out = m.push("b", 1.1, 1, "b2")                 # equal stamps: lower rank first
    assert [e[4] for e in out] == ["b2", "a2"]
    assert m.push("a", 1.0, 2, "late") is None      # older than what was handed on
    # b goes silent: a is released once it is max_delay ahead
    assert m.push("a", 1.5, 2, "a3") == []
    assert [e[4] for e in m.push("a", 2.6, 2, "a4")] == ["a3"]
    m.drop_stream("b")
    assert [e[4] for e in m.push("a", 2.7, 2, "a5")] == ["a4", "a5"]
