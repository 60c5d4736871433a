"""The recorder over DDS: what sensor_driver publishes is what read_recording reads back.

One simulated run serves the module: sensor_driver simulates 12 s of the default experiment
(deterministic: its seed) at 4x real time to two recorders, the ``recorder`` node (A) and the
``rig-record`` command (B).  A is stopped with SIGINT: its folder appears only then and holds
every message with the published stamps and values.  B is killed (SIGKILL) mid-recording
(after the data, before a clean stop): its folder never appears, the partial folder beside it
is not a readable recording, and ``rig-record --recover`` turns it into one holding every
message of the complete MCAP chunks — an exact prefix of what was published.
"""
from __future__ import annotations

import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from ros_helpers import Listener, wait_until  # noqa: E402

from rig_identification.io.recording import RecordingError, read_recording  # noqa: E402
from rig_identification.model.experiment import load_experiment  # noqa: E402
from rig_identification.model.simulator import simulate  # noqa: E402
from rig_identification.nodes.demo import Graph  # noqa: E402
from rig_identification.nodes.recorder import partial_folder  # noqa: E402
from rig_identification.nodes.topics import EXCITER_TOPIC, IMU_TOPIC, INCLINOMETER_TOPIC, LOAD_CELL_PREFIX  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
EXPERIMENT = REPO / "config" / "rigs" / "default.yaml"
DURATION = 12.0
BIN = Path(sys.executable).parent


def streams(sensors) -> dict:
    """topic -> TimeSeries of a SensorData."""
    out = {IMU_TOPIC: sensors.imu, EXCITER_TOPIC: sensors.exciter,
           INCLINOMETER_TOPIC: sensors.inclinometer}
    out.update({LOAD_CELL_PREFIX + n: s for n, s in sensors.load_cells.items()})
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("recorder")
    sim = simulate(load_experiment(EXPERIMENT).with_overrides(duration=DURATION))
    g = Graph(workdir=tmp / "nodes", domain_id=random.Random().randint(100, 232))
    lis = Listener(g.domain_id, sim.rig.cable_names)
    out_a, out_b = tmp / "rec_a", tmp / "rec_b"
    b_log = open(tmp / "rig-record.log", "wb")
    try:
        g.start("recorder_a", {"rig": str(EXPERIMENT), "output": str(out_a)},
                module="rig_identification.nodes.recorder", args=["--ros-args", "-r", "__node:=recorder_a"])
        b = subprocess.Popen([str(BIN / "rig-record"), str(out_b), "--rig", str(EXPERIMENT),
                              "--ros-args", "-r", "__node:=recorder_b"],
                             env=g.env, stdout=b_log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        g.procs["recorder_b"] = b
        g.start("sensor_driver", {"experiment": str(EXPERIMENT), "duration": DURATION, "rate": 4.0,
                                  "start_delay": 1.0, "exit_when_done": True, "wait_timeout": 60.0,
                                  "wait_for": ["/rig/imu:2", "/rig/load_cells/*:2", "/rig/exciter/wrench:2",
                                               "/rig/inclinometer:2"]})
        wait_until(lambda: lis.status.get("state") == "done", 60.0, "the driver to finish", g)
        total = lis.status["total"]

        def received(node):
            d = lis.diag.get(node, {})
            return all(d.get(f"rx {t}") == n for t, n in total.items())
        wait_until(lambda: received("/recorder_a") and received("/recorder_b"), 30.0, "both recorders to receive "
                   "everything", info=lambda: f"{total}\n{lis.diag.get('/recorder_a')}\n{lis.diag.get('/recorder_b')}")
        time.sleep(0.5)  # written (write_period 0.05 s)
        seen_before_stop = {"a": out_a.exists(), "a_partial": partial_folder(out_a).is_dir(), "b": out_b.exists()}
        b.send_signal(signal.SIGKILL)
        b.wait(timeout=10)
        g.procs["recorder_a"].send_signal(signal.SIGINT)
        code_a = g.procs["recorder_a"].wait(timeout=15)
        yield sim, total, out_a, out_b, seen_before_stop, code_a, g
    finally:
        lis.close()
        g.stop()
        b_log.close()


def test_a_clean_stop_writes_every_published_message(run):
    sim, total, out_a, _, seen, code_a, g = run
    assert code_a == 0, g.log("recorder_a")
    assert not seen["a"] and seen["a_partial"], seen  # written aside until the stop
    assert out_a.is_dir() and not partial_folder(out_a).exists()
    rec = read_recording(out_a)
    assert rec.warnings == []
    got, want = streams(rec.sensors), streams(sim.sensors)
    assert {t: len(s) for t, s in got.items()} == total == {t: len(s) for t, s in want.items()}
    for topic, s in want.items():
        np.testing.assert_array_equal(got[topic].t, s.t, err_msg=topic)  # header stamps, to the ns
        np.testing.assert_allclose(got[topic].data, s.data, rtol=0, atol=0, err_msg=topic)
    assert rec.rig.cable_names == sim.rig.cable_names and rec.rig.mass == sim.rig.mass  # the experiment's rig
    assert "recording complete" in g.log("recorder_a")


def test_a_killed_recorder_leaves_no_recording_but_a_recoverable_prefix(run, tmp_path):
    sim, total, _, out_b, seen, _, g = run
    partial = partial_folder(out_b)
    assert not seen["b"] and not out_b.exists()
    assert partial.is_dir() and (partial / "rig.yaml").is_file()
    with pytest.raises(RecordingError, match="cannot read the bag"):
        read_recording(partial)  # no summary, no metadata.yaml: not a recording until recovered
    p = subprocess.run([str(BIN / "rig-record"), "--recover", str(partial)], capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 0, p.stderr
    assert f"recovered {out_b}" in p.stdout
    rec = read_recording(out_b)
    got, want = streams(rec.sensors), streams(sim.sensors)
    n_imu = len(got[IMU_TOPIC])
    # rosbags writes a chunk per MiB (~5 s of these streams): 12 s of data leave 2 complete
    # chunks on disk and lose the rest
    assert 0.3 * total[IMU_TOPIC] < n_imu < total[IMU_TOPIC], (n_imu, total)
    t_cut = got[IMU_TOPIC].t[-1]
    for topic, s in want.items():
        k = len(got[topic].t)
        assert 0 < k < len(s.t), topic
        np.testing.assert_array_equal(got[topic].t, s.t[:k], err_msg=topic)  # an exact prefix
        np.testing.assert_array_equal(got[topic].data, s.data[:k], err_msg=topic)
        assert abs(got[topic].t[-1] - t_cut) < 0.2, topic  # every topic cut at about the same arrival time
    # recovering twice refuses to overwrite
    again = subprocess.run([str(BIN / "rig-record"), "--recover", str(partial)], capture_output=True, text=True,
                           timeout=60)
    assert again.returncode == 2 and "already exists" in again.stderr


def test_the_recorder_refuses_an_existing_output(run):
    _, _, out_a, _, _, _, g = run
    p = subprocess.run([str(BIN / "rig-record"), str(out_a), "--rig", str(EXPERIMENT)], env=g.env,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, p.stdout + p.stderr
    assert f"{out_a}: already exists" in p.stderr and "Traceback" not in p.stderr
