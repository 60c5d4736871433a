"""Faults on the node graph (issue 6), over DDS as separate processes, plus the pieces that
need no DDS: the serialized-message codec the nodes use at 1 kHz, and the recorder.

* a load cell that stops publishing for 12 s (sensor_driver ``silence``): every node reports
  it on /diagnostics (ERROR "stopped" while silent, OK again after), the identifier refuses a
  window over the gap naming the topic and the span, and with no window start or end set fits
  after it;
* the tracker killed (SIGKILL) in the middle of a run and started again: it re-initialises
  on the moving body; the identifier, which reads the raw streams, fits as if nothing happened;
* a recording written and read back has every message of every topic.

Each graph test has its own ROS_DOMAIN_ID; 60 s of data replayed at 4x real time (the restart:
90 s at 3x).
"""
from __future__ import annotations

import json
import random
import signal
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip("rclpy")

from ros_helpers import Listener, wait_until  # noqa: E402

from rig_identification.io.recording import read_recording  # noqa: E402
from rig_identification.io.recording_writer import write_recording  # noqa: E402
from rig_identification.model.experiment import load_experiment  # noqa: E402
from rig_identification.model.simulator import simulate  # noqa: E402
from rig_identification.nodes import codec  # noqa: E402
from rig_identification.nodes.demo import Graph  # noqa: E402
from rig_identification.nodes.diagnostics import diagnostic_values  # noqa: E402
from rig_identification.nodes.merge import StampMerger  # noqa: E402
from rig_identification.nodes.messages import stamp_to_sec  # noqa: E402
from rig_identification.nodes.topics import IMU_TOPIC, LOAD_CELL_PREFIX, POSE_TOPIC, WRENCH_TOPIC  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
RATE = 4.0
KEYS = ("ixx", "iyy", "izz")
WAIT_FOR = ["/rig/imu:3", "/rig/load_cells/*:3", "/rig/exciter/wrench:3", "/rig/inclinometer:2", "/rig/pose:2",
            "/rig/generalized_wrench:1"]


class StatusListener(Listener):
    """Listener that also keeps every diagnostic status seen: (wall time, name, level, message, values)."""

    def __init__(self, *a, **kw):
        self.history: list[tuple] = []
        super().__init__(*a, **kw)

    def _diag(self, msg):
        super()._diag(msg)
        now = time.monotonic()
        for st in msg.status:
            lvl = st.level if isinstance(st.level, int) else int.from_bytes(st.level, "little")
            self.history.append((now, st.name, lvl, st.message, diagnostic_values(st)))

    def set_params(self, node: str, values: dict) -> None:
        from rclpy.parameter import Parameter
        from rclpy.parameter_client import AsyncParameterClient
        cli = AsyncParameterClient(self.node, node)
        assert cli.wait_for_services(timeout_sec=20.0), f"parameter services of {node}"
        fut = cli.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        wait_until(fut.done, 20.0, f"setting {values} on {node}")
        assert all(r.successful for r in fut.result().results), fut.result()


def default_recording(tmp_path_factory, duration: float):
    exp = load_experiment(REPO / "config" / "rigs" / "default.yaml").with_overrides(duration=duration)
    sim = simulate(exp)
    return write_recording(tmp_path_factory.mktemp("faults") / "recording", sim.rig, sim.sensors, sim.truth), sim


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return default_recording(tmp_path_factory, 60.0)


@pytest.fixture(scope="module")
def long_recording(tmp_path_factory):
    # 90 s: under load the restarted tracker's streams were seen matching up to ~5 s of wall
    # time (15 s of data at 3x) apart, each re-initialising it; 20 s settle after the last
    # re-initialisation must still leave a window of well over min_duration
    return default_recording(tmp_path_factory, 90.0)


def start_graph(tmp: Path, rec: Path, cables, driver_extra=None, identifier_extra=None, rate=RATE, tracker_extra=None):
    g = Graph(workdir=tmp / "nodes", domain_id=random.Random().randint(120, 230))
    lis = StatusListener(g.domain_id, cables)
    rig = str(rec / "rig.yaml")
    g.start("sensor_driver", {"recording": str(rec), "rate": rate, "start_delay": 1.0, "wait_timeout": 60.0,
                              "wait_for": WAIT_FOR, **(driver_extra or {})})
    g.start("tracker", {"rig": rig, **(tracker_extra or {})})
    g.start("preprocessor", {"rig": rig})
    g.start("identifier", {"rig": rig, "min_duration": 10.0, "window_last": 30.0, **(identifier_extra or {})})
    return g, lis


def drained(lis: Listener) -> bool:
    d, total = lis.diag, lis.status.get("total", {})
    return (lis.status.get("state") == "done"
            and d.get("/identifier", {}).get(f"rx {IMU_TOPIC}") == total.get(IMU_TOPIC)
            and lis.counts.get(WRENCH_TOPIC) == d.get("/preprocessor", {}).get(f"tx {WRENCH_TOPIC}", -1))


def relative_errors(d: dict, truth: dict) -> dict:
    tru = truth["inertia_about_cg"]
    return {k: abs(d["inertia_about_cg"][k] - tru[k]) / abs(tru[k]) for k in KEYS}


def test_a_silent_load_cell_is_reported_and_not_fitted_over(recording, tmp_path):
    rec, sim = recording
    topic = LOAD_CELL_PREFIX + "c1"
    # max_delay is data time: at RATE x real time the tracker's 5 s default tolerates only 5 / RATE s
    # of wall-time lag between topics, and under a loaded CI machine a topic lagged more (its late
    # samples refused by the stamp merger); the lab's 5 s of wall time, scaled to the replay
    g, lis = start_graph(tmp_path, rec, sim.rig.cable_names, {"silence": [f"{topic}:20.0:32.0"]},
                         identifier_extra={"settle_after_gap": 5.0, "window_last": 45.0},
                         tracker_extra={"max_delay": 5.0 * RATE})
    try:
        wait_until(lambda: drained(lis), 120.0, "the replay to finish and drain", g)
        time.sleep(1.2)
        # reported while silent: ERROR "stopped" on that topic, from every node that reads it
        for node in ("/tracker", "/preprocessor", "/identifier"):
            seen = [h for h in lis.history if h[1] == f"{node}: {topic}" and h[2] == 2]
            assert seen and "stopped" in seen[0][3], (node, [h[1:4] for h in lis.history if h[1].startswith(node)])
            # ... while the IMU stream of the same node stayed OK at that moment
            t_err = seen[0][0]
            imu = [h for h in lis.history if h[1] == f"{node}: {IMU_TOPIC}" and abs(h[0] - t_err) < 0.5]
            if node != "/preprocessor":
                assert imu and imu[-1][2] == 0, (node, imu)
            top = [h for h in lis.history if h[1] == node and abs(h[0] - t_err) < 0.01]
            assert top and top[-1][2] == 2 and topic in top[-1][3], top
        # recovered (OK again once it publishes again, before the end of the data: then every
        # input goes silent), the gap on record with its stamps
        hist = [h for h in lis.history if h[1] == f"/identifier: {topic}"]
        t_err = next(h[0] for h in hist if h[2] == 2)
        assert any(h[2] == 0 and h[0] > t_err for h in hist), [h[2:4] for h in hist]
        last = hist[-1]
        t_first = float(sim.sensors.imu.t[0])
        a, b = (float(x) - t_first for x in last[4]["last_gap"].split())
        assert a == pytest.approx(20.0 - 0.005, abs=1e-4) and b == pytest.approx(32.0, abs=1e-4), (a, b)
        # nothing else was lost or rejected
        for node in ("/tracker", "/preprocessor", "/identifier"):
            assert lis.diag[node][f"rx {topic}"] == lis.status["total"][topic]
            rejected = {k: v for k, v in lis.diag[node].items() if k.startswith("rejected") and v}
            assert not rejected, (node, rejected, [h[3] for h in lis.history if h[1] == node and h[2] == 1])
        # a window over the gap is refused, naming the topic and the span
        lis.set_params("/identifier", {"window_start": 5.0, "window_end": 40.0})
        r = lis.call("/identifier/identify_rig_model")
        assert not r.success
        err = json.loads(r.message)["error"]
        # the span: from the last sample before (t=19.995 s) to the first after (t=32.0 s)
        assert f"no data on {topic} from t=19.99 to 32.00 s" in err, err
        # a window before it fits
        lis.set_params("/identifier", {"window_start": 0.0, "window_end": 20.0})
        r = lis.call("/identifier/identify_rig_model")
        assert r.success, r.message
        assert json.loads(r.message)["window"]["end_relative"] <= 20.0
        # no window start or end: the last window_last s after the gap (and settle_after_gap)
        lis.set_params("/identifier", {"window_start": None, "window_end": None})
        r = lis.call("/identifier/identify_rig_model")
        assert r.success, r.message
        d = json.loads(r.message)
        assert d["window"]["start_relative"] >= 32.0 + 5.0 - 0.01
        assert any("gap" in w and "after it" in w for w in d["warnings"]), d["warnings"]
        assert d["verdict"] == "ok" and max(relative_errors(d, sim.truth).values()) < 0.01, \
            (d["verdict"], relative_errors(d, sim.truth))
    finally:
        lis.close()
        g.stop()


def test_tracker_killed_and_restarted_mid_run_recovers(long_recording, tmp_path):
    rec, sim = long_recording
    # 3x: a process restart takes a few s of wall time, the fit needs 20 s + 10 s after it
    g, lis = start_graph(tmp_path, rec, sim.rig.cable_names, rate=3.0)
    try:
        wait_until(lambda: lis.status.get("state") == "publishing", 60.0, "the driver to start", g)
        t0 = time.monotonic()
        wait_until(lambda: lis.diag.get("/tracker", {}).get("tx /rig/pose", 0) > 8.0 * 200, 30.0,
                   "8 s of poses", g)
        g.procs["tracker"].send_signal(signal.SIGKILL)
        g.procs["tracker"].wait(timeout=10)
        killed_at = time.monotonic() - t0
        del g.procs["tracker"]
        time.sleep(0.5)
        # start_timeout 0: the new tracker starts on whatever stream came first, the others
        # join later (what a slow discovery did on CI: Izz 13 % off when the tracker tracked
        # on without them); it must re-initialise with every stream
        g.start("tracker", {"rig": str(rec / "rig.yaml"), "start_timeout": 0.0})
        wait_until(lambda: drained(lis), 150.0, "the replay to finish and drain", g)
        time.sleep(1.2)
        # the outage was reported (the preprocessor's pose input stale or stopped), and ended
        po = [h for h in lis.history if h[1] == f"/preprocessor: {POSE_TOPIC}"]
        assert any(h[2] >= 1 and h[0] - t0 > killed_at for h in po), [h[2:4] for h in po]
        t_err = next(h[0] for h in po if h[2] >= 1 and h[0] - t0 > killed_at)
        assert any(h[2] == 0 and h[0] > t_err for h in po), [h[2:4] for h in po]
        # the new tracker initialised on the moving body and tracks: poses again to the end
        assert lis.diag["/tracker"]["rx /rig/imu"] > 0
        assert lis.diag["/tracker"]["tx /rig/pose"] > 25.0 * 200, lis.diag["/tracker"]
        # the identifier reads the raw streams: the tracker's outage leaves its fit alone
        lis.set_params("/identifier", {"window_last": 20.0})
        r = lis.call("/identifier/identify_rig_model")
        assert r.success, r.message
        d = json.loads(r.message)
        assert not any("gap" in w for w in d["warnings"]), d["warnings"]
        errs = relative_errors(d, sim.truth)
        assert d["verdict"] == "ok" and max(errs.values()) < 0.01, (d["verdict"], errs, d["window"], d["inertia_std"])
        # and nothing was lost on the way apart from the outage itself
        assert lis.status["published"] == lis.status["total"]
        # the killed reader held the reliable writers back for the DDS lease (3 s) at most
        assert lis.status["achieved"]["rate"] > 0.6 * 3.0, lis.status["achieved"]
        assert lis.diag["/identifier"]["rx /rig/imu"] == lis.status["total"][IMU_TOPIC]
    finally:
        lis.close()
        g.stop()


# --- no DDS -------------------------------------------------------------------------------

def test_message_layout_matches_the_rclpy_serializer():
    """The batch codec reads and writes exactly what rclpy's serializer does; messages it does
    not expect (another frame, another size) go the slow way and are named."""
    from geometry_msgs.msg import WrenchStamped
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import Imu
    rng = np.random.default_rng(6)
    t = 1.75e9 + np.cumsum(rng.uniform(0.001, 0.002, 5))
    for layout, mtype in ((codec.imu_layout(), Imu), (codec.odometry_layout(), Odometry),
                          (codec.wrench_layout("load_cell_c0"), WrenchStamped)):
        vals = rng.normal(size=(5, len(layout.fields)))
        raws = layout.encode(t, vals)
        for i, raw in enumerate(raws):
            m = deserialize_message(raw, mtype)
            assert stamp_to_sec(m.header.stamp) == pytest.approx(t[i], abs=1e-9)
            got = [float(codec.get_path(m, p)) for p in layout.fields]
            assert got == vals[i].tolist()
            # and back (alignment padding is not defined: compare what decodes, not bytes)
            tt, vv, bad = layout.decode([serialize_message(m)])
            assert not bad and vv[0].tolist() == vals[i].tolist() and tt[0] == stamp_to_sec(m.header.stamp)
        # a foreign frame id and a message of another size among them
        odd = mtype()
        odd.header.frame_id = "camera"
        raws[2] = serialize_message(odd)
        tt, vv, bad = layout.decode(raws)
        assert list(bad) == [2] and "'camera'" in bad[2]
        keep = [0, 1, 3, 4]
        np.testing.assert_array_equal(vv[keep], vals[keep])
        np.testing.assert_allclose(tt[keep], t[keep], atol=1e-9)


def test_stamp_merger_lookahead_keeps_stamp_order():
    """A slow stream (50 Hz) does not hold a fast one (1 kHz) back for a whole period, and the
    merged feed is still in stamp order."""
    m = StampMerger(["fast", "slow"], max_delay=5.0, lookahead=0.75)
    fast = 100.0 + np.arange(0, 1.0, 0.001)
    slow = 100.0 + np.arange(0, 1.0, 0.02)
    out, lag = [], []
    j = 0
    for i, t in enumerate(fast):
        while j < len(slow) and slow[j] <= t:
            out += m.push("slow", slow[j], 0, None)
            j += 1
        got = m.push("fast", t, 2, None)
        out += got
        if i > 300:
            lag.append(t - max([e[0] for e in out if e[3] == "fast"], default=-np.inf))
    out += m.flush()
    stamps = [(e[0], e[1]) for e in out]
    assert stamps == sorted(stamps) and len(out) == len(fast) + len(slow)
    assert max(lag) <= 0.005 + 1e-9  # at most a quarter of the slow period


def test_recording_round_trip_keeps_every_message(tmp_path):
    """What the recorder writes is every sample of every stream: counts and stamps per topic
    read back from the bag, and the bag's own message count."""
    exp = load_experiment(REPO / "config" / "rigs" / "default.yaml").with_overrides(duration=6.0)
    sim = simulate(exp)
    out = write_recording(tmp_path / "rec", sim.rig, sim.sensors, sim.truth)
    back = read_recording(out)
    s, b = sim.sensors, back.sensors
    pairs = [("/rig/imu", s.imu, b.imu), ("/rig/exciter/wrench", s.exciter, b.exciter),
             ("/rig/inclinometer", s.inclinometer, b.inclinometer)]
    pairs += [(f"/rig/load_cells/{n}", s.load_cells[n], b.load_cells[n]) for n in s.load_cells]
    expected = {}
    for topic, a, c in pairs:
        assert len(c) == len(a), topic
        np.testing.assert_allclose(c.t, a.t, atol=1e-9, rtol=0)
        np.testing.assert_allclose(c.data, a.data, rtol=0, atol=0)
        expected[topic] = len(a)
    meta = yaml.safe_load((out / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    assert counts == expected
    assert meta["message_count"] == sum(expected.values())
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())  # no temporary folder left


def test_a_node_that_hangs_at_shutdown_still_stops():
    """nodes.runtime.shutdown_watchdog: once rclpy's context is shut down (Ctrl-C), a process
    whose clean-up hangs ends after the grace period with status 0, and says why on stderr
    with every thread's stack (where it hung)."""
    import subprocess
    import sys
    code = ("import time, rclpy\n"
            "from rig_identification.nodes.runtime import shutdown_watchdog\n"
            "rclpy.init()\n"
            "shutdown_watchdog('hanging', grace=0.5)\n"
            "rclpy.shutdown()\n"
            "def stuck_in_cleanup():\n"
            "    time.sleep(60)\n"
            "stuck_in_cleanup()\n")
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=50)
    assert p.returncode == 0, p.stderr
    assert time.monotonic() - t0 < 30
    assert "hanging: shutdown did not finish within 0.5 s" in p.stderr
    assert "stuck_in_cleanup" in p.stderr   # the stack of the hung thread
