"""The identifier node validates its fits with rig-identify's core (issue 18: a lab on ROS gets
the verdict, the widened σ and null entries for what the recording does not determine).

* No DDS: ``pipeline.stream_fit`` fed with a prepared recording's streams (the IMU, the
  generalized wrench, the tracked orientation, as the node buffers them) gives the validation
  of ``rig-identify inertia --quick`` (``pipeline.identify_recording``): the
  same checks and statistics, the same widened σ, on the clean and on the damped reference
  recordings (``ok``, ``model_error``).
* Over DDS: a rig with near-parallel cables (``scenarios`` layout "parallel", 30 s) replayed
  through sensor_driver, tracker, preprocessor and identifier: ``~/identify_inertia`` answers
  ``not_identifiable``, the undetermined entries ``null``, the verdict first in
  mass_properties_client's table and the entries "not determined".
"""
from __future__ import annotations

import json
import random
import subprocess
import sys

import numpy as np
import pytest
from conftest import recording

from rig_identification.estimation.identification import identify_inertia
from rig_identification.io.recording import read_recording
from rig_identification.io.recording_writer import write_recording
from rig_identification.pipeline.offline import identify_recording
from rig_identification.pipeline.prepare import prepare_recording

ENTRIES = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def node_validation(rec):
    """The node's path on a recording: the fit of the streams (as pipeline.stream_fit.identify_window fits them),
    validated by pipeline.stream_fit from a StreamBuffer fed as the node feeds it."""
    from rig_identification.pipeline.stream_fit import StreamBuffer, validate_stream_fit
    prep = prepare_recording(rec)
    result = identify_inertia(rec.rig, prep.t, prep.gyro_body, prep.torque)
    buf = StreamBuffer(900.0)
    buf.add_imu(prep.sensors.imu.t, prep.sensors.imu.data)
    buf.add_wrench(prep.t, np.column_stack([prep.force, prep.torque]))
    buf.add_pose(prep.poses.t, prep.poses.quaternion)
    lo, hi = prep.window
    return validate_stream_fit(rec.rig, result, buf.snapshot(lo, hi), lo, hi)


@pytest.mark.parametrize("name, verdict", [("visible_case16_clean", "ok"), ("visible_case16_damped", "model_error")])
def test_node_validation_is_rig_identify_quick(name, verdict):
    rec = read_recording(recording(name))
    off = identify_recording(rec)
    node = node_validation(rec)
    v, vo = node.validation, off.validation
    assert v is not None and v.verdict == vo.verdict == verdict, (v and v.summary, vo.summary)
    assert [c.name for c in v.checks] == [c.name for c in vo.checks]
    assert {"weight", "segments", "sub_bands"} <= {c.name for c in v.checks}
    for c, co in zip(v.checks, vo.checks):
        assert c.passed == co.passed, c.name
        assert c.statistic == pytest.approx(co.statistic, rel=1e-9), c.name
    assert node.weight_surplus == pytest.approx(off.weight_surplus, rel=1e-9)
    # the same σ, widened the same way under model_error
    np.testing.assert_allclose(node.inertia_std, off.inertia_std, rtol=1e-9)
    assert node.uncertainty == off.uncertainty
    if verdict == "model_error":
        assert "widened to the validation's spread" in node.uncertainty
        assert vo.summary in node.warnings
    d = node.to_dict(t0=float(rec.sensors.t_start))
    assert d["validation"]["verdict"] == verdict


def test_node_validation_without_poses_skips_the_weight_check_and_says_so():
    from rig_identification.pipeline.stream_fit import StreamBuffer, validate_stream_fit
    rec = read_recording(recording("visible_case16_clean"))
    prep = prepare_recording(rec)
    result = identify_inertia(rec.rig, prep.t, prep.gyro_body, prep.torque)
    buf = StreamBuffer(900.0)
    buf.add_imu(prep.sensors.imu.t, prep.sensors.imu.data)
    buf.add_wrench(prep.t, np.column_stack([prep.force, prep.torque]))
    lo, hi = prep.window
    result = validate_stream_fit(rec.rig, result, buf.snapshot(lo, hi), lo, hi)
    assert "weight" not in [c.name for c in result.validation.checks]
    assert "segments" in [c.name for c in result.validation.checks]
    assert any("weight check did not run" in w for w in result.warnings)


# --- over DDS ---------------------------------------------------------------------------------

DURATION = 30.0
RATE = 3.0


@pytest.fixture(scope="module")
def parallel_graph(tmp_path_factory):
    pytest.importorskip("rclpy")
    from test_nodes import Listener, wait_until

    from rig_identification.design.scenarios import simulate_random
    from rig_identification.nodes.demo import Graph
    _, sim = simulate_random(3100, 4, "parallel", [], DURATION)
    tmp = tmp_path_factory.mktemp("parallel")
    rec = write_recording(tmp / "recording", sim.rig, sim.sensors, sim.truth)
    g = Graph(workdir=tmp / "nodes", domain_id=random.Random().randint(100, 230))
    rig = str(rec / "rig.yaml")
    lis = Listener(g.domain_id, sim.rig.cable_names)
    wait_for = ["/rig/imu:3", "/rig/load_cells/*:3", "/rig/pose:2", "/rig/generalized_wrench:2"]
    if sim.sensors.exciter is not None:
        wait_for.append("/rig/exciter/wrench:3")
    if sim.sensors.inclinometer is not None:
        wait_for.append("/rig/inclinometer:2")
    try:
        g.start("sensor_driver", {"recording": str(rec), "rate": RATE, "start_delay": 1.0, "wait_timeout": 60.0,
                                  "wait_for": wait_for})
        g.start("tracker", {"rig": rig})
        g.start("preprocessor", {"rig": rig})
        g.start("identifier", {"rig": rig, "min_duration": 10.0})
        wait_until(lambda: lis.status.get("state") == "done", 120.0, "the driver to finish", g)

        def drained():
            d = lis.diag
            return (d.get("/identifier", {}).get("rx /rig/generalized_wrench")
                    == d.get("/preprocessor", {}).get("tx /rig/generalized_wrench", -1)
                    and d.get("/identifier", {}).get("rx /rig/pose") == d.get("/tracker", {}).get("tx /rig/pose", -1))
        wait_until(drained, 120.0, "the pipeline to drain", g)
        yield g, lis, sim, rec
    finally:
        lis.close()
        g.stop()


def test_identify_service_answers_not_identifiable_with_null_entries(parallel_graph):
    g, lis, sim, rec = parallel_graph
    r = lis.call("/identifier/identify_inertia")
    assert r.success, r.message
    d = json.loads(r.message)
    v = d["validation"]
    assert v["verdict"] == "not_identifiable", v["summary"]
    assert {"ixx", "iyy"} <= set(v["undetermined"]), v["undetermined"]
    for k in ENTRIES:
        if k in v["undetermined"]:
            assert d["inertia_about_cg"][k] is None and d["inertia_std"][k] is None, k
        else:
            assert isinstance(d["inertia_about_cg"][k], float) and d["inertia_std"][k] > 0, k
    assert d["principal_moments"] is None
    assert v["advice"] and v["summary"] in d["warnings"]
    json.dumps(d, allow_nan=False)   # null, never NaN
    # the client says the verdict first and prints the undetermined entries as such
    p = subprocess.run([sys.executable, "-m", "rig_identification.nodes.client", "--timeout", "20"],
                       env=g.env, capture_output=True, text=True, timeout=90)
    assert p.returncode == 0, p.stdout + p.stderr
    lines = p.stdout.splitlines()
    assert lines[2] == v["summary"] and lines[2].startswith("verdict: NOT IDENTIFIABLE"), lines[:3]
    # the table's rows are the moments and products (Ixx … Iyz), the tensor keys' capitals
    rows = {ln.split()[0].lower(): ln for ln in lines if ln.split() and ln.split()[0].startswith("I")
            and ln.split()[0].lower() in ENTRIES}
    for k in v["undetermined"]:
        assert "not determined" in rows[k], rows[k]
