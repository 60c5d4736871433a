"""The identifier node's ~/diagnose service, in process: the node's raw-stream buffer is fed
the first 70 s of the reference damped recording (through the same methods its subscriptions
call), the service callback runs as a lab tool's call would, and the answer names the
concealed viscous damping; the improved tensor becomes the node's published one."""
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
    rclpy.init(args=["--ros-args", "-p", f"rig:={rec.path / 'rig.yaml'}", "-p", "diagnose_seconds:=70.0"])
    node = None
    try:
        node = IdentifierNode()
        imu = s.imu.window(t0, t1)
        node._add_imu(imu.t.tolist(), imu.data)
        for n in rec.rig.cable_names:
            c = s.load_cells[n].window(t0, t1)
            node._to_cg(f"/rig/load_cells/{n}", "add_tension", [(n, t, x) for t, x in zip(c.t, c.data[:, 0])])
        e = s.exciter.window(t0, t1)
        node._to_cg("/rig/exciter/wrench", "add_exciter", [(t, x, y) for t, (x, y) in zip(e.t, e.data)])
        i = s.inclinometer.window(t0, t1)
        node._to_cg("/rig/inclinometer", "add_inclinometer", [(t, xy) for t, xy in zip(i.t, i.data)])
        resp = node.service_node._guarded_call(Trigger.Response(), node.diagnose, "diagnose")
        assert resp.success, resp.message
        d = json.loads(resp.message)
        assert d["mismatch"] and d["effects"][0]["name"] == "viscous_damping", d["effects"]
        tru = next(x for x in rec.truth["effects"] if x["name"] == "viscous_damping")
        assert abs(d["effects"][0]["parameters"]["angular"] / tru["angular"] - 1) < 0.15
        # the published tensor is the improved one, and the damping took Izz back to the truth
        J = node.last_inertia
        after, before = d["inertia_about_cg_after"], d["inertia_about_cg_before"]
        assert np.allclose([J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]],
                           [after[k] for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")])
        izz = rec.truth["inertia_about_cg"]["izz"]
        assert abs(after["izz"] / izz - 1) < 0.01 < abs(before["izz"] / izz - 1), (before["izz"], after["izz"], izz)
    finally:
        if node is not None:
            node.service_node.destroy_node()
            node.destroy_node()
        rclpy.try_shutdown()
