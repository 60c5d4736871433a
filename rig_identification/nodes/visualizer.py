"""rig_visualizer: the rig for RViz and Foxglove — transform world → body and markers.

A node of its own rather than part of the tracker: it only looks (BEST_EFFORT readers of the
1 kHz streams exert no back-pressure and may drop samples; it draws the latest), and the
tracker stays lean.

Parameters:
  rig (string, required)   rig description (rig.yaml, recording folder or experiment file)
  rate (double, 20.0)      Hz at which the transform and the markers are published
  publish_tf (bool, true)  also broadcast the transform on /tf (tf2_msgs/TFMessage) when the
                           tf2_msgs package is installed (a ROS computer; not in the pip install,
                           which has no tf2_msgs: then the node says so once and publishes
                           /rig/transform only)
  world_frame (world), body_frame (body), load_cell_frame (load_cell_{cable})
                           expected frames of the inputs (frames.py); world_frame is the frame
                           of the markers and the transform's parent
  executor (string, events)  events | single

Subscribes (BEST_EFFORT, latest sample used):
  /rig/pose                nav_msgs/Odometry, frame world_frame, child body_frame (tracker)
  /rig/load_cells/<cable>  geometry_msgs/WrenchStamped, frame load_cell_frame: tension = force.z N
  /rig/mass_properties     geometry_msgs/InertiaStamped, frame body_frame (latched; identifier)

Publishes (once a pose has arrived, at ``rate`` while new input arrives, else once per second;
stamps = the latest pose's stamp):
  /rig/transform   geometry_msgs/TransformStamped world_frame → body_frame (translation = the
                   body origin in world, m; rotation body → world).  Foxglove uses it as a
                   transform; always published.
  /tf              tf2_msgs/TFMessage with the same transform (publish_tf, when installed)
  /rig/markers     visualization_msgs/MarkerArray, every marker in world_frame (RViz and
                   Foxglove show it without any TF), namespaces (id 0 each):
                     ceiling_anchors    SPHERE_LIST, the cables' ceiling anchors
                     body_anchors       SPHERE_LIST, the cables' body anchors (tracked pose)
                     cables             LINE_LIST, one line per cable, coloured by tension
                                        T / (m g / N): 0 blue, 1 green, >= 2 red; grey before
                                        the first tension
                     body               CUBE, the bounding box of the body anchors, the CG and
                                        the exciter (at least 5 cm thick), translucent
                     center_of_gravity  SPHERE, 10 cm, at the CG (the latest
                                        /rig/mass_properties com, else rig.yaml; absent when
                                        neither knows it)
                     inertia_ellipsoid  SPHERE scaled to the uniform solid ellipsoid with the
                                        identified mass and tensor (semi-axes
                                        a_i = sqrt(5 (I_j + I_k - I_i) / (2 m)) along the
                                        principal axes), at the CG; once /rig/mass_properties
                                        carries a tensor (not all zero)
  /diagnostics     message counts
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import InertiaStamped, Point, TransformStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from scipy.spatial.transform import Rotation
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from ..io.rig import Rig
from .codec import PersistentReason, odometry_layout, wrench_layout
from .diagnostics import Diagnostics
from .frames import Endpoint, declare_frame_ids, log_interface
from .inputs import InputGuard, RawInput
from .messages import set_stamp, set_xyz, xyz
from .parameters import load_rig_param
from .qos import LATCHED_QOS
from .runtime import run
from .topics import LOAD_CELL_PREFIX, MASS_PROPERTIES_TOPIC, POSE_TOPIC

try:  # on a ROS computer; the pip wheels of this package's setup have no tf2_msgs
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None

TRANSFORM_TOPIC = "/rig/transform"
MARKERS_TOPIC = "/rig/markers"
TF_TOPIC = "/tf"
#: readers of the 1 kHz streams: BEST_EFFORT (no back-pressure on the pipeline), latest kept
VIEW_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)
MIN_BOX = 0.05  # m: the body's box is at least this thick along every axis
KEEP_ALIVE = 1.0  # s: with no new input the transform and markers are repeated this often


# --- geometry (no ROS) --------------------------------------------------------------------

@dataclass(frozen=True)
class Ellipsoid:
    """Semi-axes (3,) m along the columns of ``axes`` (3, 3), body frame (a rotation)."""

    semi_axes: np.ndarray
    axes: np.ndarray


def inertia_ellipsoid(mass: float, inertia: np.ndarray) -> Ellipsoid:
    """The uniform solid ellipsoid of ``mass`` kg whose inertia tensor about its centre is
    ``inertia`` (3, 3) kg·m² (tensor entries, body axes): principal moments I_i along the
    eigenvectors, semi-axes a_i = sqrt(5 (I_j + I_k - I_i) / (2 m)).  A moment that breaks the
    triangle inequality (not a rigid body) gets a zero semi-axis.  Raises ValueError for a
    non-positive mass or a non-symmetric / non-finite tensor."""
    J = np.asarray(inertia, float)
    if not mass > 0:
        raise ValueError(f"mass {mass}: must be > 0 kg")
    if J.shape != (3, 3) or not np.isfinite(J).all() or not np.allclose(J, J.T, atol=1e-9 * max(1.0, abs(J).max())):
        raise ValueError("inertia: expected a finite symmetric (3, 3) tensor")
    moments, axes = np.linalg.eigh(J)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    total = moments.sum()
    semi = np.sqrt(np.maximum(5.0 * (total - 2.0 * moments) / (2.0 * mass), 0.0))
    return Ellipsoid(semi, axes)


def body_box(rig: Rig, cg: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3,) and size (3,) m, body frame, of the bounding box of the body anchors, the
    CG ``cg`` (default rig.yaml's, when known) and the exciter; every side at least
    :data:`MIN_BOX`."""
    pts = [rig.body_anchors]
    cg = rig.center_of_gravity if cg is None else cg
    if cg is not None:
        pts.append(np.reshape(cg, (1, 3)))
    if rig.exciter is not None:
        pts.append(np.reshape(rig.exciter.position, (1, 3)))
    p = np.vstack(pts)
    lo, hi = p.min(0), p.max(0)
    return 0.5 * (lo + hi), np.maximum(hi - lo, MIN_BOX)


def tension_colour(ratio: float) -> tuple[float, float, float]:
    """RGB of a cable whose tension is ``ratio`` times its share of the weight: 0 blue,
    1 green, 2 and more red (linear in between); NaN (no tension yet) grey."""
    if not np.isfinite(ratio):
        return (0.6, 0.6, 0.6)
    r = float(np.clip(ratio, 0.0, 2.0))
    if r <= 1.0:
        return (0.0, r, 1.0 - r)
    return (r - 1.0, 2.0 - r, 0.0)


# --- the node ----------------------------------------------------------------------------

class VisualizerNode(Node):
    """Node ``rig_visualizer`` (see the module docstring)."""

    def __init__(self):
        super().__init__("rig_visualizer")
        self.declare_parameter("rig", "")
        self.declare_parameter("rate", 20.0)
        self.declare_parameter("publish_tf", True)
        self.declare_parameter("executor", "events")
        self.frames = frames = declare_frame_ids(self, ("load_cell", "world", "body"))
        rate = float(self.get_parameter("rate").value)
        if not rate > 0:
            raise ValueError(f"parameter rate = {rate}: must be > 0 Hz")
        rig = load_rig_param(self)
        self.rig = rig
        self.share = rig.mass * rig.gravity / len(rig.cables)
        self.guard = InputGuard(self)
        self.diag = Diagnostics(self, self.guard)
        self.pose_in = RawInput(self, self.guard, POSE_TOPIC,
                                       odometry_layout(frames.world, frames.body, hinted=True), VIEW_QOS)
        self.cells = {n: RawInput(self, self.guard, LOAD_CELL_PREFIX + n,
                                         wrench_layout(frames.load_cell_frame(n), "load_cell_frame"), VIEW_QOS)
                      for n in rig.cable_names}
        self.mp_sub = self.create_subscription(InertiaStamped, MASS_PROPERTIES_TOPIC, self._on_mass_properties,
                                               LATCHED_QOS)
        self.tf_pub = self.create_publisher(TransformStamped, TRANSFORM_TOPIC, 10)
        self.marker_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, 10)
        outputs = [Endpoint(self.tf_pub, f"{frames.world} -> {frames.body}"),
                   Endpoint(self.marker_pub, f"frame {frames.world}")]
        self.tf2_pub = None
        if self.get_parameter("publish_tf").value:
            if TFMessage is None:
                self.get_logger().info(f"tf2_msgs is not installed: no {TF_TOPIC}; the transform is on "
                                       f"{TRANSFORM_TOPIC} and every marker is in frame {frames.world}")
            else:
                self.tf2_pub = self.create_publisher(TFMessage, TF_TOPIC, 100)
                outputs.append(Endpoint(self.tf2_pub, f"{frames.world} -> {frames.body}"))
        self.pose: tuple[float, np.ndarray, np.ndarray] | None = None  # stamp s, position (3,), quaternion xyzw
        self.tension = {n: float("nan") for n in rig.cable_names}
        self.cg = rig.center_of_gravity
        self.ellipsoid: Ellipsoid | None = None
        self.fresh, self.t_sent = False, -KEEP_ALIVE
        self.create_timer(1.0 / rate, self._tick)
        log_interface(self, [self.pose_in.endpoint(), *(c.endpoint() for c in self.cells.values()),
                                    Endpoint(self.mp_sub, f"frame {frames.body}, latched")], outputs)
        self.get_logger().info(f"ready: rig {rig.source}, {rate:g} Hz")

    def _on_mass_properties(self, msg) -> None:
        if msg.header.frame_id != self.frames.body:
            self.guard.reject(MASS_PROPERTIES_TOPIC, PersistentReason(
                f"frame_id {msg.header.frame_id!r}, expected {self.frames.body!r} (set by parameter body_frame)"))
            return
        i = msg.inertia
        J = np.array([[i.ixx, i.ixy, i.ixz], [i.ixy, i.iyy, i.iyz], [i.ixz, i.iyz, i.izz]], float)
        com = np.array(xyz(i.com), float)
        if not np.isfinite(com).all() or not np.isfinite(J).all():
            self.guard.reject(MASS_PROPERTIES_TOPIC, "non-finite centre of gravity or tensor")
            return
        self.cg = com
        self.fresh = True
        if np.any(J != 0.0):
            try:
                self.ellipsoid = inertia_ellipsoid(i.m, J)
            except ValueError as e:
                self.guard.reject(MASS_PROPERTIES_TOPIC, str(e))

    def _tick(self) -> None:
        """Take the latest inputs; publish when something new arrived, else once per
        :data:`KEEP_ALIVE` s (markers and the transform are not latched: a viewer that
        connects later gets them within that time)."""
        t, vals = self.pose_in.take()
        fresh = self.fresh
        if len(t):
            v = vals[-1]
            self.pose = (float(t[-1]), v[:3].copy(), v[3:7].copy())
            fresh = True
        for name, inp in self.cells.items():
            tt, vv = inp.take()
            if len(tt):
                self.tension[name] = float(vv[-1, 2])
                fresh = True
        now = time.monotonic()
        if self.pose is None or not (fresh or now - self.t_sent >= KEEP_ALIVE):
            self.fresh = fresh
            return
        self.fresh, self.t_sent = False, now
        stamp, p, q = self.pose
        tf = TransformStamped()
        set_stamp(tf.header, stamp, self.frames.world)
        tf.child_frame_id = self.frames.body
        set_xyz(tf.transform.translation, p)
        o = tf.transform.rotation
        o.x, o.y, o.z, o.w = (float(x) for x in q)
        self.tf_pub.publish(tf)
        self.diag.count_tx(TRANSFORM_TOPIC)
        if self.tf2_pub is not None:
            self.tf2_pub.publish(TFMessage(transforms=[tf]))
            self.diag.count_tx(TF_TOPIC)
        self.marker_pub.publish(self.markers(stamp, p, Rotation.from_quat(q)))
        self.diag.count_tx(MARKERS_TOPIC)

    def markers(self, stamp: float, p: np.ndarray, R: Rotation) -> MarkerArray:
        """The MarkerArray of the rig for the body at position ``p`` (3,) m, rotation ``R``
        (body → world); every marker in the world frame."""
        rig = self.rig

        def marker(ns: str, kind: int, rgba, scale) -> Marker:
            m = Marker(ns=ns, id=0, type=kind, action=Marker.ADD)
            set_stamp(m.header, stamp, self.frames.world)
            m.pose.orientation.w = 1.0
            m.color = ColorRGBA(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))
            set_xyz(m.scale, scale)
            return m

        def place(m: Marker, centre_body: np.ndarray, rot: Rotation) -> None:
            set_xyz(m.pose.position, p + R.apply(centre_body))
            o = m.pose.orientation
            o.x, o.y, o.z, o.w = (float(x) for x in rot.as_quat())

        def points(a: np.ndarray) -> list[Point]:
            return [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in a]

        out = []
        ceiling = marker("ceiling_anchors", Marker.SPHERE_LIST, (0.5, 0.5, 0.5, 1.0), (0.08, 0.08, 0.08))
        ceiling.points = points(rig.ceiling_anchors)
        out.append(ceiling)
        anchors_world = p + R.apply(rig.body_anchors)
        body_pts = marker("body_anchors", Marker.SPHERE_LIST, (1.0, 0.55, 0.0, 1.0), (0.08, 0.08, 0.08))
        body_pts.points = points(anchors_world)
        out.append(body_pts)
        cables = marker("cables", Marker.LINE_LIST, (1.0, 1.0, 1.0, 1.0), (0.02, 0.0, 0.0))
        pairs = np.stack([rig.ceiling_anchors, anchors_world], axis=1).reshape(-1, 3)
        cables.points = points(pairs)
        for name in rig.cable_names:
            r, g, b = tension_colour(self.tension[name] / self.share)
            cables.colors += [ColorRGBA(r=r, g=g, b=b, a=1.0)] * 2
        out.append(cables)
        centre, size = body_box(rig, self.cg)
        box = marker("body", Marker.CUBE, (0.3, 0.6, 0.9, 0.3), size)
        place(box, centre, R)
        out.append(box)
        if self.cg is not None:
            cg = marker("center_of_gravity", Marker.SPHERE, (0.9, 0.1, 0.1, 1.0), (0.1, 0.1, 0.1))
            place(cg, self.cg, R)
            out.append(cg)
            if self.ellipsoid is not None:
                e = self.ellipsoid
                ell = marker("inertia_ellipsoid", Marker.SPHERE, (0.8, 0.2, 0.8, 0.35), 2.0 * e.semi_axes)
                place(ell, self.cg, R * Rotation.from_matrix(e.axes))
                out.append(ell)
        return MarkerArray(markers=out)


def main(argv=None) -> int:
    return run(VisualizerNode, argv, "rig_visualizer", __doc__)


if __name__ == "__main__":
    sys.exit(main())
