"""ROS conventions of the nodes, over DDS: frame ids as parameters, remapped topics, the
start-up interface line, and the rig_visualizer's transform and markers.

Each test starts one node on its own ROS_DOMAIN_ID and feeds it from this process.
"""
from __future__ import annotations

import random
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

rclpy = pytest.importorskip("rclpy")

from ros_helpers import Listener, wait_until  # noqa: E402

from rig_identification.io.rig import rig_from_dict  # noqa: E402
from rig_identification.nodes.demo import Graph  # noqa: E402
from rig_identification.nodes.messages import set_stamp, set_xyz, stamp_to_sec  # noqa: E402
from rig_identification.nodes.qos import LATCHED_QOS, SENSOR_QOS  # noqa: E402
from rig_identification.nodes.topics import LOAD_CELL_PREFIX, MASS_PROPERTIES_TOPIC, POSE_TOPIC  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
EXPERIMENT = REPO / "config" / "rigs" / "default.yaml"


def imu_msg(t: float, frame: str):
    from sensor_msgs.msg import Imu
    m = Imu()
    set_stamp(m.header, t, frame)
    m.angular_velocity.x = 0.01
    m.linear_acceleration.z = 9.81
    m.orientation_covariance[0] = -1.0
    return m


def test_frame_ids_are_parameters_and_topics_remap(tmp_path):
    """An identifier told imu_frame:=imu_link and remapped to /lab/imu accepts IMU messages in
    imu_link on /lab/imu, rejects those in 'imu' with one warning in all (not one per message
    nor one per 5 s), and said at start-up what it reads."""
    from sensor_msgs.msg import Imu
    g = Graph(workdir=tmp_path / "nodes", domain_id=random.Random().randint(100, 232))
    lis = Listener(g.domain_id, [])
    try:
        g.start("identifier", {"rig": str(EXPERIMENT), "imu_frame": "imu_link"},
                args=["--ros-args", "-r", "/rig/imu:=/lab/imu"])
        wait_until(lambda: "ready" in g.log("identifier"), 30.0, "the identifier to start", g)
        pub = lis.node.create_publisher(Imu, "/lab/imu", SENSOR_QOS)
        wait_until(lambda: pub.get_subscription_count() >= 1, 20.0, "the identifier to subscribe to /lab/imu", g)
        t0 = 1.75e9
        sent = {"good": 0, "bad": 0}

        def send(k: int, frame: str):
            for _ in range(k):
                n = sent["good"] + sent["bad"]
                pub.publish(imu_msg(t0 + 0.005 * n, frame))
                sent["good" if frame == "imu_link" else "bad"] += 1

        def counts():
            d = lis.diag.get("/identifier", {})
            return d.get("rx /rig/imu"), d.get("rejected /rig/imu"), d.get("buffered imu")

        send(3, "imu")
        send(20, "imu_link")
        wait_until(lambda: counts() == (23, 3, 20), 20.0, "23 IMU messages, 3 rejected", g, info=counts)
        time.sleep(5.5)  # longer than the throttle period of ordinary rejections (5 s)
        send(3, "imu")
        send(10, "imu_link")
        wait_until(lambda: counts() == (36, 6, 30), 20.0, "36 IMU messages, 6 rejected", g, info=counts)
        log = g.log("identifier")
        warnings = [line for line in log.splitlines() if "frame_id 'imu'" in line]
        assert len(warnings) == 1, warnings
        assert "/lab/imu (remapped /rig/imu)" in warnings[0] and "expected 'imu_link'" in warnings[0]
        assert "parameter imu_frame" in warnings[0]
        interface = [line for line in log.splitlines() if "interface:" in line]
        assert len(interface) == 1, interface
        assert "/lab/imu [sensor_msgs/msg/Imu, frame imu_link]" in interface[0]
        assert "/rig/load_cells/c0 [geometry_msgs/msg/WrenchStamped, frame load_cell_c0]" in interface[0]
        assert "/rig/mass_properties [geometry_msgs/msg/InertiaStamped, frame body" in interface[0]
        assert "/identifier/estimate_cg" in interface[0]
        assert not g.dead()
    finally:
        lis.close()
        g.stop()


def test_visualizer_publishes_transform_and_markers(tmp_path):
    import yaml
    from geometry_msgs.msg import InertiaStamped, TransformStamped, WrenchStamped
    from nav_msgs.msg import Odometry
    from visualization_msgs.msg import MarkerArray
    rig = rig_from_dict(yaml.safe_load(EXPERIMENT.read_text())["rig"])
    g = Graph(workdir=tmp_path / "nodes", domain_id=random.Random().randint(100, 232))
    lis = Listener(g.domain_id, [])
    got = {"markers": [], "tf": []}
    node = lis.node
    node.create_subscription(MarkerArray, "/rig/markers", got["markers"].append, 10)
    node.create_subscription(TransformStamped, "/rig/transform", got["tf"].append, 10)
    try:
        g.start("rig_visualizer", {"rig": str(EXPERIMENT), "rate": 20.0},
                module="rig_identification.nodes.visualizer")
        pose_pub = node.create_publisher(Odometry, POSE_TOPIC, SENSOR_QOS)
        cells = {n: node.create_publisher(WrenchStamped, LOAD_CELL_PREFIX + n, SENSOR_QOS)
                 for n in rig.cable_names}
        mp_pub = node.create_publisher(InertiaStamped, MASS_PROPERTIES_TOPIC, LATCHED_QOS)
        wait_until(lambda: pose_pub.get_subscription_count() >= 1 and all(
            c.get_subscription_count() >= 1 for c in cells.values()), 30.0, "the visualizer to subscribe", g)
        R = Rotation.from_euler("xyz", [0.02, -0.03, 0.5])
        p = np.array([2.0, 2.6, -2.1])
        share = rig.mass * rig.gravity / len(rig.cables)
        t = 1.75e9

        def publish(k):
            o = Odometry()
            set_stamp(o.header, t + 0.01 * k, "world")
            o.child_frame_id = "body"
            set_xyz(o.pose.pose.position, p)
            q = R.as_quat()
            o.pose.pose.orientation.x, o.pose.pose.orientation.y = q[0], q[1]
            o.pose.pose.orientation.z, o.pose.pose.orientation.w = q[2], q[3]
            pose_pub.publish(o)
            for i, (n, pub) in enumerate(cells.items()):
                w = WrenchStamped()
                set_stamp(w.header, t + 0.01 * k, f"load_cell_{n}")
                w.wrench.force.z = share * (1.0, 0.0, 2.0, 1.0)[i]
                pub.publish(w)

        sent = [0]

        def fed_and_drawn() -> bool:
            """Publish one more pose and tensions (BEST_EFFORT readers may miss the first ones
            while discovery settles); True once the markers show them."""
            publish(sent[0])
            sent[0] += 1
            m = got["markers"]
            return bool(got["tf"] and m and len(m[-1].markers) == 5 and m[-1].markers[2].colors[0].g > 0.99
                        and stamp_to_sec(got["tf"][-1].header.stamp) > t)
        wait_until(fed_and_drawn, 20.0, "markers", g, step=0.05)
        tf = got["tf"][-1]
        assert (tf.header.frame_id, tf.child_frame_id) == ("world", "body")
        tr, rq = tf.transform.translation, tf.transform.rotation
        np.testing.assert_allclose([tr.x, tr.y, tr.z], p)
        np.testing.assert_allclose((Rotation.from_quat([rq.x, rq.y, rq.z, rq.w]) * R.inv()).magnitude(), 0, atol=1e-9)
        k = (stamp_to_sec(tf.header.stamp) - t) / 0.01  # the stamp of one of the poses sent
        assert abs(k - round(k)) < 1e-3 and 0 < round(k) < sent[0], k
        ms = {m.ns: m for m in got["markers"][-1].markers}
        assert set(ms) == {"ceiling_anchors", "body_anchors", "cables", "body", "center_of_gravity"}
        assert {m.header.frame_id for m in ms.values()} == {"world"}
        anchors = np.array([[q.x, q.y, q.z] for q in ms["body_anchors"].points])
        np.testing.assert_allclose(anchors, p + R.apply(rig.body_anchors), atol=1e-9)
        np.testing.assert_allclose([[q.x, q.y, q.z] for q in ms["ceiling_anchors"].points], rig.ceiling_anchors)
        cable = ms["cables"]
        assert len(cable.points) == 2 * len(rig.cables)
        colours = [(c.r, c.g, c.b) for c in cable.colors[::2]]
        assert colours == [(0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]  # T/share 1, 0, 2, 1
        cg = ms["center_of_gravity"].pose.position
        np.testing.assert_allclose([cg.x, cg.y, cg.z], p + R.apply(rig.center_of_gravity), atol=1e-9)
        box = ms["body"]
        lo = np.minimum(rig.body_anchors.min(0), np.minimum(rig.center_of_gravity, rig.exciter.position))
        hi = np.maximum(rig.body_anchors.max(0), np.maximum(rig.center_of_gravity, rig.exciter.position))
        np.testing.assert_allclose([box.scale.x, box.scale.y, box.scale.z], hi - lo)
        bp = box.pose.position
        np.testing.assert_allclose([bp.x, bp.y, bp.z], p + R.apply(0.5 * (lo + hi)), atol=1e-9)
        # an identified tensor: the inertia ellipsoid appears, at the published CG
        m = InertiaStamped()
        set_stamp(m.header, t, "body")
        m.inertia.m, (m.inertia.ixx, m.inertia.iyy, m.inertia.izz) = 1810.0, (2894.0, 695.0, 3101.0)
        set_xyz(m.inertia.com, [0.01, -0.02, 0.03])
        mp_pub.publish(m)
        n_before = len(got["markers"])
        wait_until(lambda: len(got["markers"]) > n_before and len(got["markers"][-1].markers) == 6, 20.0,
                   "the inertia ellipsoid", g)
        ms = {mk.ns: mk for mk in got["markers"][-1].markers}
        ell = ms["inertia_ellipsoid"]
        assert ell.header.frame_id == "world"
        I1, I2, I3 = sorted((2894.0, 695.0, 3101.0))  # eigenvalue order of the principal axes
        semi = np.sqrt(5.0 * np.array([I2 + I3 - I1, I1 + I3 - I2, I1 + I2 - I3]) / (2 * 1810.0))
        np.testing.assert_allclose([ell.scale.x, ell.scale.y, ell.scale.z], 2 * semi, rtol=1e-9)
        c = ell.pose.position
        np.testing.assert_allclose([c.x, c.y, c.z], p + R.apply([0.01, -0.02, 0.03]), atol=1e-9)
        try:
            import tf2_msgs  # noqa: F401
            has_tf2 = True
        except ImportError:
            has_tf2 = False
        log = g.log("rig_visualizer")
        assert ("tf2_msgs is not installed" in log) == (not has_tf2)
        assert "interface:" in log and "/rig/markers [visualization_msgs/msg/MarkerArray, frame world]" in log
        assert not g.dead()
    finally:
        lis.close()
        g.stop()
