"""The identifier node's ~/diagnose service, in process: the node's raw-stream buffer is fed
the first 70 s of the reference damped recording (through the same methods its subscriptions
call), the service callback runs as a lab tool's call would, and the rig model's diagnosis
names the concealed viscous damping, told apart from quadratic drag and dry friction, at its
true size; the tensor is within 3 σ of the truth."""
from __future__ import annotations

import json

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from conftest import recording  # noqa: E402

from rig_identification.io.recording import read_recording  # noqa: E402


def test_diagnose_service_names_the_damping():
    from std_srvs.srv import Trigger

    from rig_identification.nodes.identifier_node import IdentifierNode
    rec = read_recording(recording("visible_case16_damped"))
    s = rec.sensors
    t0, t1 = s.t_start, s.t_start + 70.0
    rclpy.init(args=["--ros-args", "-p", f"rig:={rec.path / 'rig.yaml'}", "-p", "window_last:=70.0"])
    node = None
    try:
        node = IdentifierNode()
        imu = s.imu.window(t0, t1)
        node._add_imu(imu.t.tolist(), imu.data)
        for n in rec.rig.cable_names:
            c = s.load_cells[n].window(t0, t1)
            node._add_raw(f"/rig/load_cells/{n}", "add_tension", [(n, t, x) for t, x in zip(c.t, c.data[:, 0])])
        e = s.exciter.window(t0, t1)
        node._add_raw("/rig/exciter/wrench", "add_exciter", [(t, x, y) for t, (x, y) in zip(e.t, e.data)])
        i = s.inclinometer.window(t0, t1)
        node._add_raw("/rig/inclinometer", "add_inclinometer", [(t, xy) for t, xy in zip(i.t, i.data)])
        resp = node.service_node._guarded_call(Trigger.Response(), node.diagnose, "diagnose")
        assert resp.success, resp.message
        d = json.loads(resp.message)
        dg = d["diagnosis"]
        assert dg["named"] == ["viscous_damping"] and dg["extensions"] == [] and not dg["advice"], dg
        tru = next(x for x in rec.truth["effects"] if x["name"] == "viscous_damping")
        bd = d["body_damping"]
        for k in ("linear", "angular"):
            assert abs(bd[k] - tru[k]) < max(3 * bd[k + "_std"], 0.02 * tru[k]), (k, bd, tru)
        assert d["verdict"] == "ok", d["verdict"]
        truth, std = rec.truth["inertia_about_cg"], d["inertia_std"]
        z = {k: (d["inertia_about_cg"][k] - truth[k]) / std[k] for k in truth}
        assert max(abs(v) for v in z.values()) < 3, z
        # the published tensor is the fit's
        J, fit = node.last_inertia, d["inertia_about_cg"]
        assert np.allclose([J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]],
                           [fit[k] for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")])
    finally:
        if node is not None:
            node.service_node.destroy_node()
            node.destroy_node()
        rclpy.try_shutdown()
