"""identifier: buffers the gyro and the generalized wrench; fits the inertia tensor on request.

Thin node around rig_identification.estimation.identification.identify_inertia (the same fit as
the offline ``rig-identify``) over its buffered streams, validated by the offline core
(pipeline.stream_fit: the verdict, widened σ and null undetermined entries of ``rig-identify inertia
--quick``).

Parameters (the window ones are read at each request; set them with ros2 param set):
  rig (string, required)   path of the rig description (rig.yaml, with body.center_of_gravity)
  window_start (double, unset)  window start, s after the first IMU sample received
  window_end (double, unset)    window end, s after the first IMU sample (unset: the latest sample)
  window_last (double, unset)   only the last N s of the window
  settle (double, 5.0)     the window never starts before this many s after the first IMU
                           sample (tracker convergence; as rig-identify)
  settle_after_gap (double, 20.0)  with no window set and a gap in an input stream (a sensor
                           or node that stopped), the fit starts this many s after the gap: a
                           tracker (re)initialised on the moving body starts from zero velocity,
                           its position filter needs ~15 s to forget that
  min_duration (double, 10.0)  refuse to fit a window shorter than this, s
  band_hz (double[2], [] = auto)  pass band of the fit, Hz
  precision_target_pct (double, 1.0)  % at 95 % asked of every entry: the answer's precision block says
                           which entries fall short (as rig-identify inertia --target)
  block_s, iterations      identify_inertia parameters (defaults: the core's)
  max_seconds (double, 900.0)  seconds of data kept in the buffer (pipeline.stream_fit.StreamBuffer)
  debug_fit_delay (double, 0.0)  testing aid: each fit takes this much longer, s
  cg_capture_seconds (double, 10.0)  averaging window of a static CG state, s
  dummy_mass (double, unset), dummy_position (double[3], unset)  the dummy mass, kg, and the
                           body-frame position of its CG, m, if rig.yaml has no dummy_mass
  (rig.yaml may omit body.center_of_gravity: then only the CG services work, and
  identify_inertia says to write the estimated CG into a rig.yaml first:
  ``mass_properties_client cg-estimate --write-rig OUT.yaml``)
  input_reliability (string, reliable)  reliable | best_effort (QoS of the subscriptions)
  batch_period (double, 0.01)  the inputs are taken serialized and decoded in batches every
                           this many s (inputs.RawInput)
  stale_after, stopped_after (double, 0.5, 2.0)  /diagnostics: an input silent this long (wall
                           time, s) is reported WARN stale, ERROR stopped
  executor (string, events)  executor of the data node (events | single)
  imu_frame (imu), load_cell_frame (load_cell_{cable}), exciter_frame (exciter),
  inclinometer_frame (inclinometer)  expected frame ids of the raw inputs (frames.py)
  body_frame (body)        expected frame of /rig/generalized_wrench (and child frame of /rig/pose),
                           written on /rig/mass_properties
  world_frame (world)      expected frame of /rig/pose

The rig parameter may also name a recording folder or an experiment file.  Topic names are
remapped the ROS way (--ros-args -r /rig/imu:=/my/imu); the node logs its resolved inputs,
outputs and services once at start-up ("interface: ...").

Gaps: two consecutive stamps of an input stream (any of the subscriptions below) further
apart than max(0.1 s, 1.5 sampling periods) are a gap (a sensor or a node that stopped; the
offline rule of io.bad_spans.find_bad_spans).  The window rule is the core's
(estimation.fit_window): no fit runs over a gap; a window that contains one is refused,
naming the topic and the span (a window that only ends or starts inside one is cut at its
edge); with no window set, the fit uses the data after the last gap plus settle_after_gap
(and says so in "warnings").  A stream silent until now counts as a gap up to the window's
end.

Subscribes (RELIABLE, KEEP_ALL):
  /rig/imu                 sensor_msgs/Imu, frame imu_frame (gyro, rad/s; specific force for the CG states)
  /rig/generalized_wrench  geometry_msgs/WrenchStamped, frame body_frame (torque about the CG, N·m;
                           the force, N, for the validation's weight check)
  /rig/pose                nav_msgs/Odometry, world_frame -> body_frame (the tracked orientation, for
                           the validation's weight check)
  /rig/load_cells/<cable>, /rig/exciter/wrench, /rig/inclinometer  raw streams of the static
                           CG experiment (averaged on capture)

Services (std_srvs/Trigger; ``message`` is JSON):
  ~/identify_inertia  fit over the window, validated as ``rig-identify inertia --quick``
                      validates (pipeline.stream_fit; pipeline.apply_validation); success=true: the
                      JSON of ``rig-identify inertia --json`` (InertiaResult.to_dict with t0 the
                      first IMU sample: "validation" with the verdict ok | model_error |
                      not_identifiable, its checks and segments, σ widened, undetermined entries
                      null; window and segment times in s from the first IMU sample, the stamps in
                      start_stamp/end_stamp; start_relative/end_relative = start/end) plus
                      "received" counts; success=false: {"error": "..."} (too little data,
                      no motion, a gap in the window, or "busy" while another fit runs)
  ~/capture_cg_baseline  the static CG experiment, step 1: average the last
                      cg_capture_seconds of the raw streams with the body at rest (no dummy)
  ~/capture_cg_dummy  step 2: the same with the dummy mass fixed (rig.yaml dummy_mass, or the
                      dummy_mass / dummy_position parameters)
  ~/estimate_cg       step 3: the CG from the two states (rig_identification.statics, as
                      ``rig-identify cg``); success=true: CgResult.to_dict(); publishes it
  ~/diagnose          the same call as ~/identify_rig_model (as ``rig-identify diagnose``, whose
                      JSON is ``rig-identify inertia``'s): the rig model's diagnosis of the last
                      ``diagnose_seconds`` of the raw streams is its JSON's ``diagnosis`` (what was
                      tested, named, added) and ``rigid_body_fit`` (the fit before the extensions)
  ~/identify_rig_model  the rig model of ``rig-identify inertia`` (every sensor an output: the
                      tensions, gyro, accelerometer, inclinometer and exciter force; the mass, CG
                      and tensor fitted together) on the last ``diagnose_seconds`` of the raw
                      streams; the CG's prior the last ~/estimate_cg with its σ, else rig.yaml's;
                      success=true: the JSON of ``rig-identify inertia --json``
                      (RigModelResult.to_dict); under verdict ok the fitted mass, CG and tensor
                      are published on /rig/mass_properties.  The rig day in service order:
                      capture_cg_baseline, capture_cg_dummy, estimate_cg, identify_rig_model
  ~/status            buffered samples: {"imu": n, "wrench": n, "duration": s, "busy": bool, ...}
  (served by the helper node ``<name>_services`` under this node's name, see below)

Publishes:
  /rig/mass_properties  geometry_msgs/InertiaStamped after each successful fit or CG
                        estimate, frame body_frame: m kg, com = CG m (the estimate after
                        estimate_cg), ixx..izz kg·m² (tensor entries; zero until identified;
                        every entry of the fit, also those the verdict says are not
                        determined: the service's JSON has them null).
                        RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1 (a late subscriber receives it)
  /diagnostics          message counts; one status per input topic (OK / WARN stale / ERROR
                        stopped, age, rate, stamp gaps: diagnostics.Diagnostics)

Threading: the subscriptions run on the EventsExecutor in the main thread.  The rclpy
7.1.6 EventsExecutor ignores callback groups, runs only one callback at a time and cannot
run ``async`` service callbacks (rclpy issue #1473, fixed in 7.1.11), so a fit inside a
service callback would stop the message flow.  The services therefore live on a second
node (identifier_services: ``<name>_services``, service names ``/<name>/identify_inertia`` ...) spun by a
MultiThreadedExecutor in a background thread with a ReentrantCallbackGroup: a fit runs
in its own thread while the main thread keeps receiving, and a second request during a
fit is answered "busy" at once.  The fit runs on a snapshot of the buffer taken under a
lock, so incoming samples never wait for it.
"""
from __future__ import annotations

import math
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from geometry_msgs.msg import InertiaStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from ..estimation.fit_window import fit_window
from ..estimation.identification import identify_inertia
from ..estimation.precision import TARGET as PRECISION_TARGET
from ..io.recording import Recording
from ..io.rig import DummyMass
from ..model.parametrisation import to_tensor
from ..pipeline.rig_model import fit_whole_recording
from ..pipeline.stream_fit import StreamBuffer, identify_window, validate_stream_fit
from ..statics.capture import CgSession
from .codec import imu_layout, odometry_layout, vector_layout, wrench_layout
from .diagnostics import Diagnostics
from .frames import Endpoint, declare_frame_ids, log_interface
from .identifier_services import IdentifierServices
from .inputs import InputGuard, RawInput
from .messages import set_stamp, set_xyz
from .parameters import core_params, load_rig_param
from .qos import LATCHED_QOS, input_qos
from .runtime import run
from .topics import (
    EXCITER_TOPIC,
    IMU_TOPIC,
    INCLINOMETER_TOPIC,
    LOAD_CELL_PREFIX,
    MASS_PROPERTIES_TOPIC,
    POSE_TOPIC,
    WRENCH_TOPIC,
)


class IdentifierNode(Node):
    """Node ``identifier``: buffers gyro + wrench, fits on request (see the module docstring)."""

    def __init__(self):
        super().__init__("identifier")
        self.declare_parameter("rig", "")
        self.declare_parameter("executor", "events")
        dyn = ParameterDescriptor(dynamic_typing=True,
                                  description="seconds after the first IMU sample; unset = no limit")
        for name in ("window_start", "window_end", "window_last"):
            self.declare_parameter(name, None, dyn)
        self.declare_parameter("settle", 5.0)
        self.declare_parameter("settle_after_gap", 20.0)
        self.declare_parameter("min_duration", 10.0)
        self.declare_parameter("band_hz", None, ParameterDescriptor(
            dynamic_typing=True, description="[low, high] Hz pass band of the fit; unset or [] = automatic"))
        self.declare_parameter("debug_fit_delay", 0.0)
        self.declare_parameter("precision_target_pct", 100 * PRECISION_TARGET, ParameterDescriptor(
            description="% at 95 % asked of every entry (rig-identify inertia --target): the answer's 'precision'"))
        self.fit_params = core_params(self, identify_inertia, skip=("rig", "t", "omega_body", "torque"))
        buf_params = core_params(self, StreamBuffer.__init__, skip=("self",))
        qos_in = input_qos(self)
        frames = declare_frame_ids(self, ("imu", "load_cell", "exciter", "inclinometer", "world", "body"))
        self.frames = frames
        rig = load_rig_param(self)
        self.rig = rig
        # the streams the fit and its model validation read (pipeline.stream_fit); only with the CG known
        self.fits = rig.center_of_gravity is not None
        self.buffer = StreamBuffer(**buf_params) if self.fits else None
        self.declare_parameter("cg_capture_seconds", 10.0)
        self.declare_parameter("dummy_mass", None, ParameterDescriptor(dynamic_typing=True))
        self.declare_parameter("dummy_position", None, ParameterDescriptor(dynamic_typing=True))
        self.cg_session = self._new_cg_session()
        # the raw streams of the last diagnose_seconds, for ~/diagnose (same buffer class)
        self.declare_parameter("diagnose_seconds", 120.0)
        self.diag_buffer = CgSession(rig, float(self.get_parameter("diagnose_seconds").value))
        self.last_inertia = None
        self.last_cg = rig.center_of_gravity
        self.last_cg_std: np.ndarray | None = None      # the σ of a CG from ~/estimate_cg
        self.lock = threading.RLock()
        self.busy = threading.Lock()
        self.t_first_imu: float | None = None
        self.t_last_wrench: float | None = None
        self.n_imu = self.n_wrench = 0
        self.guard = InputGuard(self)
        self.diag = Diagnostics(self, self.guard, extra=self._diag_extra)
        self.pub = self.create_publisher(InertiaStamped, MASS_PROPERTIES_TOPIC, LATCHED_QOS)
        # inputs: raw subscriptions, decoded in batches every batch_period s (inputs.RawInput)
        self.declare_parameter("batch_period", 0.01)
        R = RawInput
        self.inputs = [(R(self, self.guard, IMU_TOPIC, imu_layout(frames.imu, parameter="imu_frame"),
                          qos_in), self._add_imu),
                       (R(self, self.guard, WRENCH_TOPIC, wrench_layout(frames.body, "body_frame"),
                          qos_in), self._add_wrench),
                       (R(self, self.guard, POSE_TOPIC,
                          odometry_layout(frames.world, frames.body, hinted=True), qos_in), self._add_pose)]
        for name in rig.cable_names:
            self.inputs.append((R(self, self.guard, LOAD_CELL_PREFIX + name,
                                  wrench_layout(frames.load_cell_frame(name), "load_cell_frame"), qos_in),
                                lambda t, v, n=name: self._to_cg(
                                    LOAD_CELL_PREFIX + n, "add_tension",
                                    [(n, ti, x) for ti, x in zip(t, v[:, 2].tolist())])))
        if rig.exciter is not None:
            self.inputs.append((R(self, self.guard, EXCITER_TOPIC,
                                  wrench_layout(frames.exciter, "exciter_frame"), qos_in),
                                lambda t, v: self._to_cg(EXCITER_TOPIC, "add_exciter",
                                                         [(ti, x, y) for ti, (x, y) in zip(t, v[:, :2].tolist())])))
        if rig.inclinometer is not None:
            self.inputs.append((R(self, self.guard, INCLINOMETER_TOPIC,
                                  vector_layout(frames.inclinometer, "inclinometer_frame"), qos_in),
                                lambda t, v: self._to_cg(INCLINOMETER_TOPIC, "add_inclinometer",
                                                         [(ti, xy) for ti, xy in zip(t, v[:, :2].tolist())])))
        self.create_timer(float(self.get_parameter("batch_period").value), self._drain)
        self.service_node = IdentifierServices(self)
        log_interface(self, [inp.endpoint() for inp, _ in self.inputs],
                             [Endpoint(self.pub, f"frame {frames.body}, latched")], self.service_node.trigger_services)
        self.get_logger().info(f"ready: rig {rig.source}; services {self.get_fully_qualified_name()}/"
                               "identify_inertia, identify_rig_model, diagnose, capture_cg_baseline, capture_cg_dummy, "
                               "estimate_cg, status")

    def close(self) -> None:
        """Stop and destroy the service node (called by :func:`~.runtime.run` at shutdown)."""
        self.service_node.stop()
        self.service_node.destroy_node()

    # --- data --------------------------------------------------------------------------
    def _drain(self) -> None:
        """Take every queued message (decoded and validated in batches) into the buffers."""
        with self.lock:  # the gap records too are read by the service thread
            for inp, add in self.inputs:
                t, vals = inp.take()
                if len(t):
                    add(t.tolist(), vals)

    def _add_imu(self, ts: list, vals) -> None:
        rows = vals.tolist()
        kept = []
        with self.lock:
            for i, (t, r) in enumerate(zip(ts, rows)):
                try:
                    self.cg_session.add_imu(t, r[:3], r[3:])
                    self.diag_buffer.add_imu(t, r[:3], r[3:])
                except ValueError as e:
                    self.guard.core_error(IMU_TOPIC, e)
                    continue
                kept.append(i)
                if self.t_first_imu is None:
                    self.t_first_imu = t
                self.n_imu += 1
            if self.fits and kept:
                self.buffer.add_imu([ts[i] for i in kept], vals[kept])

    def _add_wrench(self, ts: list, vals) -> None:
        """Generalized wrench samples (validated by the input guard: finite, stamps increasing)."""
        if not self.fits:
            return
        with self.lock:
            self.buffer.add_wrench(ts, vals)
            self.t_last_wrench = ts[-1]
            self.n_wrench += len(ts)

    def _add_pose(self, ts: list, vals) -> None:
        """Tracked orientations (unit quaternions; another is refused, as the preprocessor
        does) for the validation's weight check."""
        if not self.fits:
            return
        q = vals[:, 3:7]
        unit = np.abs(np.einsum("ij,ij->i", q, q) - 1.0) <= 1e-3
        for i in np.nonzero(~unit)[0].tolist():
            self.guard.reject(POSE_TOPIC, f"orientation is not a unit quaternion (|q|^2 = {q[i] @ q[i]:.4f})")
        with self.lock:
            self.buffer.add_pose([t for t, u in zip(ts, unit) if u], q[unit])

    def _to_cg(self, topic, method: str, rows) -> None:
        """Raw samples into the CG session and the diagnosis buffer (``method``: add_tension,
        add_exciter or add_inclinometer)."""
        with self.lock:
            for args in rows:
                try:
                    getattr(self.cg_session, method)(*args)
                    getattr(self.diag_buffer, method)(*args)
                except ValueError as e:
                    self.guard.core_error(topic, e)

    # --- the static CG experiment -----------------------------------------------------
    def _new_cg_session(self):
        dm, dp = self.get_parameter("dummy_mass").value, self.get_parameter("dummy_position").value
        dummy = None
        if dm is not None or dp is not None:
            try:
                dummy = DummyMass(float(dm), np.array([float(x) for x in dp]))
                ok = dummy.mass > 0 and len(dummy.position) == 3
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"parameters dummy_mass = {dm!r}, dummy_position = {dp!r}: expected kg > 0 "
                                 "and [x, y, z] m")
        return CgSession(self.rig, float(self.get_parameter("cg_capture_seconds").value), dummy)

    def capture_cg(self, which: str) -> dict:
        """Capture a static state from the buffered raw streams (snapshot under the lock,
        averaging outside it); raises ValueError/StaticsError with a clear message."""
        with self.lock:
            session = self.cg_session
            data = session.sensor_data()
        state = session.capture(which, data)
        return {"captured": which, "seconds": float(data.imu.t[-1] - data.imu.t[0]),
                "tensions": None if state.tensions is None else [float(x) for x in state.tensions],
                "warnings": list(state.warnings)}

    def estimate_cg(self) -> dict:
        result = self.cg_session.estimate()
        d = result.to_dict()
        self.last_cg = result.center_of_gravity
        self.last_cg_std = np.asarray(result.center_of_gravity_std, float)
        self._publish_mass_properties(None, result.mass, result.center_of_gravity, self.last_inertia)
        c = result.center_of_gravity
        self.get_logger().info(f"centre of gravity: {c[0]:.4f}, {c[1]:.4f}, {c[2]:.4f} m (body)")
        return d

    def diagnose(self) -> dict:
        """``~/diagnose``: :meth:`identify_rig_model` (the rig model's fit carries its diagnosis)."""
        return self.identify_rig_model()

    def identify_rig_model(self) -> dict:
        """``~/identify_rig_model`` (runs in a service thread): the rig model fitted to the
        buffered raw streams (:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`,
        as ``rig-identify inertia``), the CG's prior the last ~/estimate_cg (its σ) where there
        was one, else rig.yaml's.  Returns the result's JSON; publishes the fitted mass, CG and
        tensor under verdict ok.  Raises ValueError (RigFitError, RecordingError, RigError) with
        a clear message."""
        cg, cg_std, source = (None, None, None) if self.last_cg_std is None else \
            (self.last_cg, self.last_cg_std, f"{self.get_fully_qualified_name()}/estimate_cg")
        if cg is None and self.rig.center_of_gravity is None:
            raise ValueError(f"{self.rig.source} has no body.center_of_gravity: run the static experiment first "
                             "(capture_cg_baseline, capture_cg_dummy, estimate_cg)")
        with self.lock:
            data = self.diag_buffer.sensor_data()
        rec = Recording(self.rig, data, None, Path(f"{self.get_fully_qualified_name()} buffer"))
        res = fit_whole_recording(rec, cg, cg_std, source)
        f = res.fit
        if res.verdict == "ok":
            J = to_tensor(f.inertia)
            self.last_inertia = J
            self._publish_mass_properties(None, f.body.mass, f.body.cg, J)
        named = ", ".join(res.diagnosis.named) if res.diagnosis is not None and res.diagnosis.named else "nothing"
        self.get_logger().info(f"rig model: verdict {res.verdict}; Ixx {f.inertia[0]:.1f} Iyy {f.inertia[3]:.1f} "
                               f"Izz {f.inertia[5]:.1f} kg m^2 over {res.duration_s:.1f} s; named {named}")
        return res.to_dict()

    def _publish_mass_properties(self, stamp: float | None, mass: float, cg, J) -> None:
        """/rig/mass_properties (InertiaStamped, frame body): mass kg, CG m, tensor entries
        kg·m² (zero when J is None); stamp s (None: now)."""
        msg = InertiaStamped()
        if stamp is None:
            stamp = float(self.get_clock().now().nanoseconds) * 1e-9
        set_stamp(msg.header, stamp, self.frames.body)
        msg.inertia.m = float(mass)
        set_xyz(msg.inertia.com, cg)
        if J is not None:
            i = msg.inertia
            i.ixx, i.ixy, i.ixz = float(J[0, 0]), float(J[0, 1]), float(J[0, 2])
            i.iyy, i.iyz, i.izz = float(J[1, 1]), float(J[1, 2]), float(J[2, 2])
        self.pub.publish(msg)

    def _diag_extra(self) -> dict:
        return {"buffered imu": self.n_imu, "buffered wrench": self.n_wrench, "busy": self.busy.locked()}

    def status(self) -> dict:
        with self.lock:
            d = {"imu": self.n_imu, "wrench": self.n_wrench, "t_first_imu": self.t_first_imu,
                 "t_last_wrench": self.t_last_wrench, "busy": self.busy.locked()}
        d["duration"] = (d["t_last_wrench"] - d["t_first_imu"]) if d["t_last_wrench"] and d["t_first_imu"] else 0.0
        return d

    # --- the fit -------------------------------------------------------------------------
    def _seconds(self, name: str) -> float | None:
        if not self.has_parameter(name):  # set to "not set" (or deleted): rclpy undeclares it
            return None
        v = self.get_parameter(name).value
        if v is None or v == "":
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"parameter {name} = {v!r}: expected a number of seconds (or unset)")
        return float(v)

    def identify(self) -> dict:
        """Fit over the configured window (runs in a service thread).  Returns the result
        dict; raises ValueError (IdentificationError, bad parameters) with a clear message."""
        start, end, last = (self._seconds(n) for n in ("window_start", "window_end", "window_last"))
        settle = float(self.get_parameter("settle").value)
        settle_gap = float(self.get_parameter("settle_after_gap").value)
        min_duration = float(self.get_parameter("min_duration").value)
        band = self.get_parameter("band_hz").value
        target = self.get_parameter("precision_target_pct").value
        if isinstance(target, bool) or not isinstance(target, (int, float)) \
                or not (math.isfinite(target) and target > 0):
            raise ValueError(f"parameter precision_target_pct = {target!r}: expected a number of % > 0")
        params = dict(self.fit_params)
        for name in params:
            params[name] = self.get_parameter(name).value
        if band is not None and not (hasattr(band, "__len__") and len(band) == 0):
            try:
                lo_hz, hi_hz = (float(x) for x in band)
                ok = 0 < lo_hz < hi_hz
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"parameter band_hz = {band!r}: expected [low, high] Hz with 0 < low < high")
            params["band_hz"] = (lo_hz, hi_hz)
        if not self.fits:
            raise ValueError(f"{self.rig.source} has no body.center_of_gravity: run the static experiment "
                             "(capture_cg_baseline, capture_cg_dummy, estimate_cg; `mass_properties_client "
                             "cg-estimate --write-rig OUT.yaml` writes rig.yaml with the CG) and restart the "
                             "tracker, preprocessor and identifier with rig:=OUT.yaml")
        with self.lock:
            if self.t_first_imu is None or self.t_last_wrench is None:
                raise ValueError("no data received yet (are the sensor driver, tracker and preprocessor running?)")
            t0, t_last = self.t_first_imu, self.t_last_wrench
            received = {"imu": self.n_imu, "wrench": self.n_wrench}
            topics = [inp.topic for inp, _ in self.inputs]
            window = fit_window(t0, t_last, lambda a, b: self.guard.gaps_in(a, b, topics), start, end, last,
                                settle, settle_gap, min_duration, derived=(WRENCH_TOPIC,))
            lo, hi, notes = window.start, window.end, list(window.notes)
            streams = self.buffer.snapshot(lo, hi)
        t_fit = time.monotonic()
        result = identify_window(self.rig, streams, lo, hi, **params)
        # the model validation of rig-identify inertia (--quick: the node propagates no noise), same core
        result = replace(validate_stream_fit(self.rig, result, streams, lo, hi), precision_target=float(target) / 100)
        delay = float(self.get_parameter("debug_fit_delay").value)
        if delay > 0:
            time.sleep(delay)
        d = result.to_dict(t0=t0)   # window and segment times in s from the first IMU sample, as the CLI's
        d["window"]["start_relative"] = d["window"]["start"]   # the names of earlier answers
        d["window"]["end_relative"] = d["window"]["end"]
        d["received"] = received
        d["fit_seconds"] = time.monotonic() - t_fit
        d["warnings"] = list(d.get("warnings", [])) + notes
        J = result.inertia
        self._publish_mass_properties(result.t_end, result.mass, result.center_of_gravity, J)
        self.last_inertia = J
        self.get_logger().info(f"identified: Ixx {J[0, 0]:.1f} Iyy {J[1, 1]:.1f} Izz {J[2, 2]:.1f} kg m^2 "
                               f"over {result.t_end - result.t_start:.1f} s ({result.n_samples} samples); "
                               f"verdict {result.validation.verdict}")
        return d


def _started() -> IdentifierNode:
    """The node with its service thread running (what ``main`` spins)."""
    node = IdentifierNode()
    node.service_node.start()
    return node


def main(argv=None) -> int:
    return run(_started, argv, "identifier", __doc__)


if __name__ == "__main__":
    sys.exit(main())
