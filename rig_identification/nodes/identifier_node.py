"""identifier: buffers the raw sensor streams; fits the rig model on request.

Thin node around rig_identification.pipeline.rig_model.fit_whole_recording (the core of
``rig-identify inertia``: every sensor an output, the mass, CG and tensor fitted together) over
its buffered raw streams, and around the static CG experiment (rig_identification.statics).

Parameters (the window ones are read at each request; set them with ros2 param set):
  rig (string, required)   path of the rig description (rig.yaml)
  window_start (double, unset)  window start, s after the first IMU sample received
  window_end (double, unset)    window end, s after the first IMU sample (unset: the latest sample)
  window_last (double, 120.0)   only the last N s of the window (unset: all of it); the fit's
                           time grows with the window (docs/results.md)
  settle (double, 0.0)     the window never starts before this many s after the first IMU sample
  settle_after_gap (double, 0.0)  with no window set and a gap in an input stream (a sensor that
                           stopped), the fit starts this many s after the gap
  min_duration (double, 10.0)  refuse to fit a window shorter than this, s
  max_seconds (double, 900.0)  seconds of the raw streams kept in the buffer
  debug_fit_delay (double, 0.0)  testing aid: each fit takes this much longer, s
  cg_capture_seconds (double, 10.0)  averaging window of a static CG state, s
  dummy_mass (double, unset), dummy_position (double[3], unset)  the dummy mass, kg, and the
                           body-frame position of its CG, m, if rig.yaml has no dummy_mass
  (rig.yaml may omit body.center_of_gravity: then only the CG services work until
  ~/estimate_cg has run; the fit's CG prior is the last ~/estimate_cg with its σ, else rig.yaml's)
  input_reliability (string, reliable)  reliable | best_effort (QoS of the subscriptions)
  batch_period (double, 0.01)  the inputs are taken serialized and decoded in batches every
                           this many s (inputs.RawInput)
  stale_after, stopped_after (double, 0.5, 2.0)  /diagnostics: an input silent this long (wall
                           time, s) is reported WARN stale, ERROR stopped
  executor (string, events)  executor of the data node (events | single)
  imu_frame (imu), load_cell_frame (load_cell_{cable}), exciter_frame (exciter),
  inclinometer_frame (inclinometer)  expected frame ids of the raw inputs (frames.py)
  body_frame (body)        frame written on /rig/mass_properties

The rig parameter may also name a recording folder or an experiment file.  Topic names are
remapped the ROS way (--ros-args -r /rig/imu:=/my/imu); the node logs its resolved inputs,
outputs and services once at start-up ("interface: ...").

Gaps: two consecutive stamps of an input stream further apart than max(0.1 s, 1.5 sampling
periods) are a gap (a sensor that stopped; the offline rule of io.quality.find_bad_spans).
The window rule is the core's (estimation.fit_window): no fit runs over a gap; a window that
contains one is refused, naming the topic and the span (a window that only ends or starts
inside one is cut at its edge); with no window start or end set, the fit uses the data after
the last gap plus settle_after_gap (and says so in "warnings").  A stream silent until now counts
as a gap up to the window's end.

Subscribes (RELIABLE, KEEP_ALL):
  /rig/imu                 sensor_msgs/Imu, frame imu_frame (gyro rad/s, specific force m/s²)
  /rig/load_cells/<cable>  geometry_msgs/WrenchStamped, frame load_cell_frame (tension = force.z, N)
  /rig/exciter/wrench      geometry_msgs/WrenchStamped, frame exciter_frame (force x, y, N)
  /rig/inclinometer        geometry_msgs/Vector3Stamped, frame inclinometer_frame (roll, pitch, rad)

Services (std_srvs/Trigger; ``message`` is JSON):
  ~/identify_rig_model  the rig model of ``rig-identify inertia`` fitted to the raw streams over
                      the window; the CG's prior the last ~/estimate_cg with its σ where there was
                      one, else rig.yaml's; success=true: the JSON of ``rig-identify inertia
                      --json`` (RigModelResult.to_dict: verdict, tensor, σ against the Cramér–Rao
                      bound, the diagnosis) plus "window" {"start_relative", "end_relative": s
                      after the first IMU sample, "start_stamp", "end_stamp"}, "received" counts,
                      "fit_seconds"; under verdict ok the fitted mass, CG and tensor are published
                      on /rig/mass_properties.  success=false: {"error": "..."} (too little data, a
                      gap in the window, no CG yet, a fit that failed, or "busy" while another
                      request runs)
  ~/diagnose          the same call (the rig model's fit carries its diagnosis: the JSON's
                      ``diagnosis`` and ``rigid_body_fit``)
  ~/capture_cg_baseline  the static CG experiment, step 1: average the last
                      cg_capture_seconds of the raw streams with the body at rest (no dummy)
  ~/capture_cg_dummy  step 2: the same with the dummy mass fixed (rig.yaml dummy_mass, or the
                      dummy_mass / dummy_position parameters)
  ~/estimate_cg       step 3: the CG from the two states (rig_identification.statics, as
                      ``rig-identify cg``); success=true: CgResult.to_dict(); publishes it.
                      The rig day in service order: capture_cg_baseline, capture_cg_dummy,
                      estimate_cg, identify_rig_model
  ~/status            buffered samples: {"imu": n, "load_cells": n, "duration": s, "busy": bool, ...}
  (served by the helper node ``<name>_services`` under this node's name, see below)

Publishes:
  /rig/mass_properties  geometry_msgs/InertiaStamped after each fit of verdict ok or CG
                        estimate, frame body_frame: m kg, com = CG m, ixx..izz kg·m² (tensor
                        entries; zero until identified).
                        RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1 (a late subscriber receives it)
  /diagnostics          message counts; one status per input topic (OK / WARN stale / ERROR
                        stopped, age, rate, stamp gaps: diagnostics.Diagnostics)

Threading: the subscriptions run on the EventsExecutor in the main thread.  The rclpy
7.1.6 EventsExecutor ignores callback groups, runs only one callback at a time and cannot
run ``async`` service callbacks (rclpy issue #1473, fixed in 7.1.11), so a fit inside a
service callback would stop the message flow.  The services therefore live on a second
node (identifier_services: ``<name>_services``, service names ``/<name>/identify_rig_model`` ...)
spun by a MultiThreadedExecutor in a background thread with a ReentrantCallbackGroup: a fit
runs in its own thread while the main thread keeps receiving, and a second request during a
fit is answered "busy" at once.  The fit runs on a snapshot of the buffer taken under a
lock, so incoming samples never wait for it.
"""
from __future__ import annotations

import math
import sys
import threading
import time
from pathlib import Path

import numpy as np
from geometry_msgs.msg import InertiaStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from ..estimation.fit_window import WindowRequest, fit_window
from ..io.recording import Recording, crop, on_own_clocks
from ..io.rig import DummyMass
from ..model.parametrisation import to_tensor
from ..pipeline.rig_model import fit_whole_recording
from ..statics.capture import CgSession
from .codec import imu_layout, vector_layout, wrench_layout
from .diagnostics import Diagnostics
from .frames import Endpoint, declare_frame_ids, log_interface
from .identifier_services import IdentifierServices
from .inputs import InputGuard, RawInput
from .messages import set_stamp, set_xyz
from .parameters import load_rig_param
from .qos import LATCHED_QOS, input_qos
from .runtime import run
from .topics import (
    EXCITER_TOPIC,
    IMU_TOPIC,
    INCLINOMETER_TOPIC,
    LOAD_CELL_PREFIX,
    MASS_PROPERTIES_TOPIC,
)


class IdentifierNode(Node):
    """Node ``identifier``: buffers the raw streams, fits the rig model on request (see the module docstring)."""

    def __init__(self):
        super().__init__("identifier")
        self.declare_parameter("rig", "")
        self.declare_parameter("executor", "events")
        dyn = ParameterDescriptor(dynamic_typing=True,
                                  description="seconds after the first IMU sample; unset = no limit")
        for name in ("window_start", "window_end"):
            self.declare_parameter(name, None, dyn)
        self.declare_parameter("window_last", 120.0, ParameterDescriptor(
            dynamic_typing=True, description="only the last N s of the window; unset = all of it"))
        self.declare_parameter("settle", 0.0)
        self.declare_parameter("settle_after_gap", 0.0)
        self.declare_parameter("min_duration", 10.0)
        self.declare_parameter("max_seconds", 900.0)
        self.declare_parameter("debug_fit_delay", 0.0)
        qos_in = input_qos(self)
        frames = declare_frame_ids(self, ("imu", "load_cell", "exciter", "inclinometer", "body"))
        self.frames = frames
        rig = load_rig_param(self)
        self.rig = rig
        self.declare_parameter("cg_capture_seconds", 10.0)
        self.declare_parameter("dummy_mass", None, ParameterDescriptor(dynamic_typing=True))
        self.declare_parameter("dummy_position", None, ParameterDescriptor(dynamic_typing=True))
        self.cg_session = self._new_cg_session()
        # the raw streams of the last max_seconds: what the rig model is fitted to (same buffer class)
        self.raw = CgSession(rig, float(self.get_parameter("max_seconds").value))
        self.last_inertia = None
        self.last_cg = rig.center_of_gravity
        self.last_cg_std: np.ndarray | None = None      # the σ of a CG from ~/estimate_cg
        self.lock = threading.RLock()
        self.busy = threading.Lock()
        self.t_first_imu: float | None = None
        self.t_last_imu: float | None = None
        self.n_imu = self.n_cells = 0
        self.guard = InputGuard(self)
        self.diag = Diagnostics(self, self.guard, extra=self._diag_extra)
        self.pub = self.create_publisher(InertiaStamped, MASS_PROPERTIES_TOPIC, LATCHED_QOS)
        # inputs: raw subscriptions, decoded in batches every batch_period s (inputs.RawInput)
        self.declare_parameter("batch_period", 0.01)
        R = RawInput
        self.inputs = [(R(self, self.guard, IMU_TOPIC, imu_layout(frames.imu, parameter="imu_frame"),
                          qos_in), self._add_imu)]
        for name in rig.cable_names:
            self.inputs.append((R(self, self.guard, LOAD_CELL_PREFIX + name,
                                  wrench_layout(frames.load_cell_frame(name), "load_cell_frame"), qos_in),
                                lambda t, v, n=name: self._add_raw(
                                    LOAD_CELL_PREFIX + n, "add_tension",
                                    [(n, ti, x) for ti, x in zip(t, v[:, 2].tolist())])))
        if rig.exciter is not None:
            self.inputs.append((R(self, self.guard, EXCITER_TOPIC,
                                  wrench_layout(frames.exciter, "exciter_frame"), qos_in),
                                lambda t, v: self._add_raw(EXCITER_TOPIC, "add_exciter",
                                                           [(ti, x, y) for ti, (x, y) in zip(t, v[:, :2].tolist())])))
        if rig.inclinometer is not None:
            self.inputs.append((R(self, self.guard, INCLINOMETER_TOPIC,
                                  vector_layout(frames.inclinometer, "inclinometer_frame"), qos_in),
                                lambda t, v: self._add_raw(INCLINOMETER_TOPIC, "add_inclinometer",
                                                           [(ti, xy) for ti, xy in zip(t, v[:, :2].tolist())])))
        self.create_timer(float(self.get_parameter("batch_period").value), self._drain)
        self.service_node = IdentifierServices(self)
        log_interface(self, [inp.endpoint() for inp, _ in self.inputs],
                             [Endpoint(self.pub, f"frame {frames.body}, latched")], self.service_node.trigger_services)
        self.get_logger().info(f"ready: rig {rig.source}; services {self.get_fully_qualified_name()}/"
                               "identify_rig_model, diagnose, capture_cg_baseline, capture_cg_dummy, "
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
        with self.lock:
            for t, r in zip(ts, vals.tolist()):
                try:
                    self.cg_session.add_imu(t, r[:3], r[3:])
                    self.raw.add_imu(t, r[:3], r[3:])
                except ValueError as e:
                    self.guard.core_error(IMU_TOPIC, e)
                    continue
                if self.t_first_imu is None:
                    self.t_first_imu = t
                self.t_last_imu = t
                self.n_imu += 1

    def _add_raw(self, topic, method: str, rows) -> None:
        """Raw samples into the CG session and the fit's buffer (``method``: add_tension,
        add_exciter or add_inclinometer)."""
        with self.lock:
            for args in rows:
                try:
                    getattr(self.cg_session, method)(*args)
                    getattr(self.raw, method)(*args)
                except ValueError as e:
                    self.guard.core_error(topic, e)
                    continue
                self.n_cells += method == "add_tension"

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
        buffered raw streams over the window (:func:`~rig_identification.estimation.fit_window.fit_window`)
        by :func:`~rig_identification.pipeline.rig_model.fit_whole_recording`, as ``rig-identify
        inertia``; the CG's prior the last ~/estimate_cg (its σ) where there was one, else
        rig.yaml's.  Returns the result's JSON with the window, the received counts and the fit's
        wall time; publishes the fitted mass, CG and tensor under verdict ok.  Raises ValueError
        (FitWindowError, RigFitError, RecordingError, RigError, bad parameters) with a clear message."""
        start, end, last = (self._seconds(n) for n in ("window_start", "window_end", "window_last"))
        asked = WindowRequest(start, end, last, *(float(self.get_parameter(n).value)
                                                  for n in ("settle", "settle_after_gap", "min_duration")))
        cg, cg_std, source = (None, None, None) if self.last_cg_std is None else \
            (self.last_cg, self.last_cg_std, f"{self.get_fully_qualified_name()}/estimate_cg")
        if cg is None and self.rig.center_of_gravity is None:
            raise ValueError(f"{self.rig.source} has no body.center_of_gravity: run the static experiment first "
                             "(capture_cg_baseline, capture_cg_dummy, estimate_cg)")
        with self.lock:
            if self.t_first_imu is None or self.t_last_imu is None:
                raise ValueError("no data received yet (is the sensor driver running?)")
            t0 = self.t_first_imu
            received = {"imu": self.n_imu, "load_cells": self.n_cells}
            topics = [inp.topic for inp, _ in self.inputs]
            window = fit_window(t0, self.t_last_imu, lambda a, b: self.guard.gaps_in(a, b, topics), asked)
            data = self.raw.sensor_data()
        if window.start < data.t_start - 1e-9:
            raise ValueError(f"the window starts at t={window.start - t0:.1f} s, before the buffer's oldest sample "
                             f"(t={data.t_start - t0:.1f} s after the first IMU sample; max_seconds "
                             f"{self.get_parameter('max_seconds').value:g} s): a later window_start or a larger "
                             "max_seconds")
        t_fit = time.monotonic()
        stamps: list[str] = []       # a stream stamped on arrival put on its own clock, as the reader does
        sensors = on_own_clocks(crop(data, window.start, window.end), self.rig.topics, stamps)
        lo, hi = sensors.t_start, sensors.t_end     # the samples fitted: the window's first and last
        res = fit_whole_recording(Recording(self.rig, sensors, None, Path(f"{self.get_fully_qualified_name()} buffer"),
                                            stamps), cg, cg_std, source)
        delay = float(self.get_parameter("debug_fit_delay").value)
        if delay > 0:
            time.sleep(delay)
        f = res.fit
        if res.verdict == "ok":
            J = to_tensor(f.inertia)
            self.last_inertia = J
            self._publish_mass_properties(hi, f.body.mass, f.body.cg, J)
        named = ", ".join(res.diagnosis.named) if res.diagnosis is not None and res.diagnosis.named else "nothing"
        self.get_logger().info(f"rig model: verdict {res.verdict}; Ixx {f.inertia[0]:.1f} Iyy {f.inertia[3]:.1f} "
                               f"Izz {f.inertia[5]:.1f} kg m^2 over {res.duration_s:.1f} s; named {named}")
        d = res.to_dict()
        d["window"].update({"start_relative": lo - t0, "end_relative": hi - t0, "start_stamp": lo, "end_stamp": hi})
        d["received"] = received
        d["fit_seconds"] = time.monotonic() - t_fit
        d["warnings"] = list(d.get("warnings", [])) + list(window.notes)
        return d

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
        return {"buffered imu": self.n_imu, "buffered load cells": self.n_cells, "busy": self.busy.locked()}

    def status(self) -> dict:
        with self.lock:
            d = {"imu": self.n_imu, "load_cells": self.n_cells, "t_first_imu": self.t_first_imu,
                 "t_last_imu": self.t_last_imu, "busy": self.busy.locked()}
        d["duration"] = (d["t_last_imu"] - d["t_first_imu"]) if d["t_last_imu"] and d["t_first_imu"] else 0.0
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


def _started() -> IdentifierNode:
    """The node with its service thread running (what ``main`` spins)."""
    node = IdentifierNode()
    node.service_node.start()
    return node


def main(argv=None) -> int:
    return run(_started, argv, "identifier", __doc__)


if __name__ == "__main__":
    sys.exit(main())
