"""The static CG experiment through the identifier node's services, over DDS.

The reference static pair is replayed by sensor_driver (baseline, then the dummy state,
restamped to "now" so that time runs on as on the rig); the lab's procedure is run with the
client's verbs — ``mass_properties_client cg-capture baseline``, ``cg-capture dummy``,
``cg-estimate [--json]`` (which call ~/capture_cg_baseline, ~/capture_cg_dummy and
~/estimate_cg) — and the CG is checked against truth.yaml and against `rig-identify cg` on
the same recordings, and the published /rig/mass_properties; the ``--json`` answer saved to a
file is read back as ``rig-identify inertia --cg`` reads it, and ``cg-estimate --write-rig``
writes the identifier's rig.yaml with the estimated CG as ``rig-identify cg --write-rig`` does
(no hand edit before the shake).  rig.yaml has no centre of gravity (static experiment).
"""
from __future__ import annotations

import json
import random
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip("rclpy")

from conftest import recording  # noqa: E402
from ros_helpers import Listener, wait_until  # noqa: E402

from rig_identification.io.recording import read_recording  # noqa: E402
from rig_identification.io.rig import dump_rig, load_rig  # noqa: E402
from rig_identification.nodes.demo import Graph  # noqa: E402
from rig_identification.nodes.qos import LATCHED_QOS  # noqa: E402
from rig_identification.statics import StaticState, estimate_cg  # noqa: E402
from rig_identification.statics.handover import cg_result_from_dict, load_cg_result, rig_with_cg_text  # noqa: E402

WAIT_FOR = ["/rig/imu:1", "/rig/load_cells/*:1", "/rig/inclinometer:1"]


def client(g: Graph, *args: str) -> subprocess.CompletedProcess:
    """Run ``mass_properties_client ARGS`` on the graph's ROS domain."""
    return subprocess.run([sys.executable, "-m", "rig_identification.nodes.client", *args, "--timeout", "20"],
                          env=g.env, capture_output=True, text=True, timeout=90)


def replay(g: Graph, lis: Listener, name: str, rec) -> None:
    """Start a sensor_driver (process ``name``) replaying ``rec``; wait until it is done."""
    params = g.dir / f"{name}.params.yaml"
    params.write_text(yaml.safe_dump({"/**": {"ros__parameters": {
        "recording": str(rec), "rate": 2.0, "restamp": True, "start_delay": 1.0, "wait_for": WAIT_FOR,
        "wait_timeout": 60.0, "exit_when_done": True}}}))
    g.start(name, module="rig_identification.nodes.sensor_driver", args=["--ros-args", "--params-file", str(params)])
    wait_until(lambda: g.procs[name].poll() is not None, 90.0, f"{name} to finish")
    assert g.procs[name].returncode == 0, g.log(name)
    del g.procs[name]
    time.sleep(1.0)


def test_cg_services_on_the_reference_pair(tmp_path):
    base_path = recording("visible_case16_static/static_baseline")
    dummy_path = recording("visible_case16_static/static_dummy")
    g = Graph(workdir=tmp_path / "nodes", domain_id=random.Random().randint(200, 232))
    rig = str(base_path / "rig.yaml")
    base = read_recording(base_path)
    lis = Listener(g.domain_id, base.rig.cable_names)
    try:
        g.start("identifier", {"rig": rig, "cg_capture_seconds": 9.0})
        early = client(g, "cg-estimate")  # the verbs in the wrong order: refused, with the reason
        assert early.returncode == 1, early.stdout + early.stderr
        assert "estimate_cg refused" in early.stderr and "capture the baseline and dummy" in early.stderr
        no_cg = lis.call("/identifier/identify_rig_model")
        assert not no_cg.success and "center_of_gravity" in json.loads(no_cg.message)["error"]
        replay(g, lis, "driver_baseline", base_path)
        p = client(g, "cg-capture", "baseline")
        assert p.returncode == 0, p.stdout + p.stderr
        assert "captured the baseline state: 9.0 s of data averaged" in p.stdout
        assert "cg-capture dummy" in p.stdout  # says what comes next
        tensions = p.stdout.split("cable tensions (rig.yaml order): ")[1].split(" N")[0].split(", ")
        assert len(tensions) == len(base.rig.cables)
        np.testing.assert_allclose([float(x) for x in tensions],  # the body at rest: the recording's mean
                                   [base.sensors.load_cells[n].data.mean() for n in base.rig.cable_names], rtol=2e-3)
        replay(g, lis, "driver_dummy", dummy_path)
        p = client(g, "cg-capture", "dummy", "--json")
        assert p.returncode == 0, p.stdout + p.stderr
        assert json.loads(p.stdout)["captured"] == "dummy"
        got = {}
        lis.node.create_subscription(lis.InertiaStamped, "/rig/mass_properties",
                                     lambda m: got.setdefault("msg", m), LATCHED_QOS)
        p = client(g, "cg-estimate", "--json")
        assert p.returncode == 0, p.stdout + p.stderr
        d = json.loads(p.stdout)
        # the hand-over to the shake: `cg-estimate --json > cg.json` is a file `rig-identify inertia --cg` reads
        saved_path = tmp_path / "cg.json"
        saved_path.write_text(p.stdout)
        saved = load_cg_result(saved_path)
        np.testing.assert_array_equal(saved.center_of_gravity, d["center_of_gravity"])
        np.testing.assert_array_equal(saved.center_of_gravity_std, d["center_of_gravity_std"])
        assert saved.verdict == d["validation"]["verdict"] and saved.mass == d["mass"]
        text = client(g, "cg-estimate")  # the table: the same numbers
        assert text.returncode == 0, text.stderr
        row = next(line for line in text.stdout.splitlines() if line.startswith("CG z"))
        assert f"{d['center_of_gravity'][2]:.5f}" in row and f"{d['center_of_gravity_std'][2]:.5f}" in row
        cg, sd = np.array(d["center_of_gravity"]), np.array(d["center_of_gravity_std"])
        truth = np.array(base.truth["center_of_gravity"])
        assert np.all(np.abs(cg - truth)[:2] < 1e-3) and abs(cg[2] - truth[2]) < 12e-3
        assert np.all(np.abs(cg - truth) < 3 * sd + 1e-5)
        offline = estimate_cg(base.rig, StaticState.from_recording(base, label="baseline"),
                              StaticState.from_recording(read_recording(dummy_path), label="dummy"))
        np.testing.assert_allclose(cg, offline.center_of_gravity, atol=3 * sd.max())
        # --write-rig: the identifier's rig.yaml (its rig parameter) with the CG, as rig-identify cg --write-rig
        out = tmp_path / "rig_with_cg.yaml"
        w = client(g, "cg-estimate", "--write-rig", str(out))
        assert w.returncode == 0, w.stdout + w.stderr
        assert f"written: {out}" in w.stdout and f"rig:={out}" in w.stdout
        copy = load_rig(out)
        np.testing.assert_array_equal(copy.center_of_gravity, cg)
        assert copy.to_dict() == base.rig.with_cg(cg).to_dict()      # everything else as the identifier's rig.yaml
        text = out.read_text()
        head = [line for line in text.splitlines() if line.startswith("#")]
        assert head[0].startswith(f"# body.center_of_gravity = [{', '.join(f'{x:.5f}' for x in cg)}] m estimated by "
                                  "mass_properties_client cg-estimate (/identifier/estimate_cg)")
        assert head[1].startswith("# σ " + ", ".join(f"{x * 1e3:.2f}" for x in sd) + " mm")
        assert head[2] == f"# validation: {d['validation']['verdict']}"
        assert head[4] == "# rig description (refsim scenario visible_case16_static)"   # the original's comment
        # the same core as the offline --write-rig (rig_with_cg_text): its text from the answer
        same = rig_with_cg_text(base.rig, cg_result_from_dict(d, "answer"), ["x"], "T", None, by="y")

        def body(t):
            return "\n".join(line for line in t.splitlines() if not line.startswith("#"))
        assert body(text) == body(same) == body(dump_rig(base.rig.with_cg(cg)))
        assert same.splitlines()[1:3] == head[1:3]
        again = client(g, "cg-estimate", "--write-rig", str(out))         # an existing file: refused first
        assert again.returncode == 2 and "already exists" in again.stderr, again.stderr
        forced = client(g, "cg-estimate", "--json", "--write-rig", str(out), "--force", "--rig", rig)
        assert forced.returncode == 0, forced.stderr
        assert json.loads(forced.stdout)["written_rig"] == str(out)
        wait_until(lambda: "msg" in got, 10.0, "/rig/mass_properties")
        com = got["msg"].inertia.com
        np.testing.assert_allclose([com.x, com.y, com.z], cg, atol=1e-9)
        assert got["msg"].inertia.m == pytest.approx(d["mass"])
    finally:
        lis.close()
        g.stop()
