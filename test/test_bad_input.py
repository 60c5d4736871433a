"""Bad recordings (issue 6): each gets a clear error (exit 2) or a warning naming topic and span.

What cannot be fitted is refused by ``rig-identify inertia`` (the rig model) with one line naming
the topic or the field; what can is read and cleaned with a warning (io.recording.read_recording,
io.quality.clean_sensors, as every fit reads and cleans), and one recording carrying every
recoverable fault at once is fitted through the command line."""
import contextlib
import copy
import dataclasses
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from rig_identification.cli.main import identify_main
from rig_identification.io.quality import check_motion, clean_sensors, white_sigma
from rig_identification.io.recording import Recording, RecordingError, TimeSeries, on_own_clocks, read_recording
from rig_identification.io.recording_writer import write_recording
from rig_identification.io.stamps import regular_stamps

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def sim():
    from rig_identification.model.experiment import load_experiment
    from rig_identification.model.simulator import simulate
    exp = load_experiment(str(REPO / "config/rigs/default.yaml")).with_overrides(duration=35.0)
    rates = {k: min(v, 100.0) for k, v in exp.sensors.rates.items()}
    exp = dataclasses.replace(exp, sensors=dataclasses.replace(exp.sensors, rates=rates))
    return simulate(exp)


@pytest.fixture(scope="module")
def base(sim, tmp_path_factory):
    return write_recording(tmp_path_factory.mktemp("rec") / "base", sim.rig, sim.sensors, sim.truth)


def run(path, *extra):
    """`rig-identify inertia PATH --json --quiet EXTRA` in this process (``identify_main``, as
    test_cli_output does): (exit status, JSON or None, stderr).  An exception the command does
    not turn into exit status 2 and one line propagates."""
    # --quiet: stderr holds the warnings and the error only (no progress lines)
    argv = ["inertia", str(path), "--json", "--quiet", *map(str, extra)]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = identify_main(argv)
    assert "Traceback" not in err.getvalue(), err.getvalue()
    return code, json.loads(out.getvalue()) if code == 0 else None, err.getvalue()


def cleaned(path):
    """The recording at ``path`` read and cleaned as every fit does: (its warnings, the cleaned
    SensorData, the first IMU stamp)."""
    rec = read_recording(path)
    warnings = list(rec.warnings)
    return warnings, clean_sensors(rec, warnings), float(rec.sensors.t_start)


def same_streams(a, b):
    """Two SensorData hold the same samples (stamps and values)."""
    pairs = [(a.imu, b.imu), (a.exciter, b.exciter), (a.inclinometer, b.inclinometer)]
    pairs += [(a.load_cells[n], b.load_cells[n]) for n in a.load_cells]
    return set(a.load_cells) == set(b.load_cells) and all(
        np.array_equal(x.t, y.t) and np.array_equal(x.data, y.data) for x, y in pairs)


def make(sim, tmp_path, mutate=None, storage="mcap", rig=None):
    sensors = copy.deepcopy(sim.sensors)
    if mutate is not None:              # SensorData and TimeSeries are frozen: a mutator returns new ones
        sensors = mutate(sensors) or sensors
    return write_recording(tmp_path / "rec", rig or sim.rig, sensors, sim.truth, storage=storage)


# 1. missing topics ------------------------------------------------------------------
def test_missing_load_cell(sim, tmp_path):
    rec = make(sim, tmp_path, lambda s: dataclasses.replace(s, load_cells={n: c for n, c in s.load_cells.items()
                                                                          if n != "c2"}))
    rc, _, err = run(rec)
    assert rc == 2
    assert "/rig/load_cells/c2" in err and "missing" in err
    assert len(err.strip().splitlines()) == 1


def test_missing_imu(sim, tmp_path):
    sensors = copy.deepcopy(sim.sensors)
    from rig_identification.io.recording_writer import write_bag
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "rig.yaml").write_text((Path(sim_rec_dir(sim, tmp_path)) / "rig.yaml").read_text())
    # a bag without /rig/imu: write the load cells only
    from rig_identification.io import recording_writer as R
    orig = R.sensor_messages

    def no_imu(rig, s):
        return ((t, m, st, msg) for t, m, st, msg in orig(rig, s) if t != R.IMU_TOPIC)
    R.sensor_messages = no_imu
    try:
        write_bag(tmp_path / "rec" / "bag", sim.rig, sensors)
    finally:
        R.sensor_messages = orig
    rc, _, err = run(tmp_path / "rec")
    assert rc == 2
    assert "/rig/imu" in err and "missing" in err


def sim_rec_dir(sim, tmp_path):
    return write_recording(tmp_path / "tmp_rig", sim.rig, sim.sensors, None)


# 2. empty and truncated bags ----------------------------------------------------------
def test_empty_bag(sim, tmp_path):
    def empty(s):
        def none(ts):
            return None if ts is None else TimeSeries(ts.t[:0], ts.data[:0])
        return dataclasses.replace(s, imu=none(s.imu), load_cells={n: none(c) for n, c in s.load_cells.items()},
                                   exciter=none(s.exciter), inclinometer=none(s.inclinometer))
    rec = make(sim, tmp_path, empty)
    rc, _, err = run(rec)
    assert rc == 2
    assert "/rig/imu" in err and ("missing or empty" in err or "no messages" in err)


def test_truncated_bag(sim, tmp_path):
    rec = make(sim, tmp_path)
    f = next((rec / "bag").glob("*.mcap"))
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])
    rc, _, err = run(rec)
    assert rc == 2
    assert "bag" in err and ("truncated" in err or "cannot read" in err)
    assert len(err.strip().splitlines()) == 1


# 3. sqlite3 storage ------------------------------------------------------------------
def test_sqlite3_equals_mcap(sim, tmp_path, base):
    rec = make(sim, tmp_path, storage="sqlite3")
    assert list((rec / "bag").glob("*.db3"))
    assert same_streams(read_recording(rec).sensors, read_recording(base).sensors)


# 4. unknown extra topics ----------------------------------------------------------------
def test_unknown_topics_ignored(sim, tmp_path, base):
    from rig_identification.io import recording_writer as R
    orig = R.sensor_messages

    def extra(rig, s):
        for item in orig(rig, s):
            yield item
            if item[0] == R.INCLINOMETER_TOPIC:
                yield ("/camera/temperature", item[1], item[2], item[3])
    R.sensor_messages = extra
    try:
        rec = make(sim, tmp_path)
    finally:
        R.sensor_messages = orig
    assert same_streams(read_recording(rec).sensors, read_recording(base).sensors)


# 5. NaN / inf samples ---------------------------------------------------------------------
def test_nan_samples_dropped(sim, tmp_path):
    def nan(s):
        i = np.searchsorted(s.imu.t, s.imu.t[0] + 20.0)
        s.imu.data[i:i + 3, 1] = np.nan
        j = np.searchsorted(s.load_cells["c1"].t, s.load_cells["c1"].t[0] + 25.0)
        s.load_cells["c1"].data[j, 0] = np.inf
    warnings, s, _ = cleaned(make(sim, tmp_path, nan))
    assert any("/rig/imu" in w and "non-finite" in w and "t=" in w for w in warnings), warnings
    assert any("/rig/load_cells/c1" in w and "non-finite" in w for w in warnings), warnings
    # the three IMU samples dropped by the reader, then their 30 ms bridged by the cleaning
    assert any("/rig/imu" in w and "bridged" in w for w in warnings), warnings
    assert len(s.imu.t) == len(sim.sensors.imu.t) and np.all(np.isfinite(s.imu.data))
    assert np.all(np.isfinite(s.load_cells["c1"].data))


# 6. duplicated / out-of-order stamps ----------------------------------------------------------
def test_duplicated_and_unordered_stamps(sim, tmp_path, base):
    from rig_identification.io import recording_writer as R
    orig = R.sensor_messages

    def swapped(rig, s):  # two /rig/load_cells/c0 messages written out of stamp order
        held, n = None, 0
        for item in orig(rig, s):
            if item[0] == R.LOAD_CELL_PREFIX + "c0":
                n += 1
                if n == 1000:
                    held = item
                    continue
                yield item
                if held is not None:  # same bag time as the later one, earlier header stamp
                    yield held[0], held[1], item[2], held[3]
                    held = None
            else:
                yield item

    def dup(s):
        k = len(s.imu.t) // 3
        return dataclasses.replace(s, imu=TimeSeries(np.insert(s.imu.t, k, s.imu.t[k]),
                                                     np.insert(s.imu.data, k, s.imu.data[k], axis=0)))
    R.sensor_messages = swapped
    try:
        rec = make(sim, tmp_path, dup)
    finally:
        R.sensor_messages = orig
    warnings, _, _ = cleaned(rec)
    assert any("/rig/load_cells/c0" in w and "order" in w for w in warnings), warnings
    assert any("/rig/imu" in w and "duplicated" in w for w in warnings), warnings
    read = read_recording(rec).sensors
    assert np.all(np.diff(read.imu.t) > 0) and np.all(np.diff(read.load_cells["c0"].t) > 0)
    assert len(read.imu.t) == len(sim.sensors.imu.t)     # the copy dropped


def test_imu_stamped_on_arrival_is_put_on_its_rate(sim, tmp_path):
    """An IMU whose stamps scatter by ±4 ms about its sampling instants at 100 Hz (the 0–4 ms of a
    USB IMU stamped on arrival at 200 Hz, scaled to this fixture's rate; their mean latency is a
    constant delay, diagnose's sensor_delay) reads as gaps of 1.5 periods.  Its stamps are put
    on the stream's own rate with a warning (no gap left for the cleaning to exclude); a sample
    lost inside the run leaves a gap of one period there, the others on their own instants
    (regular_stamps); steady stamps are left alone."""
    rng = np.random.default_rng(9)

    def arrival(s):
        return dataclasses.replace(s, imu=TimeSeries(s.imu.t + rng.uniform(-0.004, 0.004, len(s.imu.t)), s.imu.data))
    warnings, s, _ = cleaned(make(sim, tmp_path, arrival))
    note = [w for w in warnings if "/rig/imu" in w and "jitter" in w]
    assert len(note) == 1 and "on the stream's own rate, 100 Hz" in note[0], warnings
    assert not any("gap" in w for w in warnings) and len(s.imu.t) == len(sim.sensors.imu.t), warnings
    t = sim.sensors.imu.t + rng.uniform(0.0, 0.008, len(sim.sensors.imu.t))
    fixed, _ = regular_stamps(t, "/rig/imu")
    assert np.allclose(np.diff(fixed), 0.01, rtol=1e-4, atol=0)
    assert np.max(np.abs(fixed - sim.sensors.imu.t - 0.004)) < 0.001       # the mean delay stays
    lost, note = regular_stamps(np.delete(t, 500), "/rig/imu")
    assert np.max(np.abs(lost - np.delete(sim.sensors.imu.t, 500) - 0.004)) < 0.001, note
    assert "1 sample(s) lost inside the runs" in note
    steady = sim.sensors.imu.t
    assert regular_stamps(steady, "/rig/imu") == (steady, None)


def test_streams_buffered_live_are_put_on_their_clocks_as_the_reader_does(sim):
    """The identifier node's buffered window (io.recording.on_own_clocks): an IMU stamped on arrival
    (0–8 ms late at 100 Hz) is put on its own clock as the reader would (the same stamps, the
    warning naming the topic), the steady streams are left as they are, and the cleaning then
    bridges no gap; left jittered, the cleaning took 1.5 periods for a gap and bridged hundreds."""
    rng = np.random.default_rng(5)
    s = copy.deepcopy(sim.sensors)
    s = dataclasses.replace(s, imu=TimeSeries(s.imu.t + rng.uniform(0.0, 0.008, len(s.imu.t)), s.imu.data))
    warnings: list[str] = []
    own = on_own_clocks(s, sim.rig.topics, warnings)
    assert len(warnings) == 1 and warnings[0].startswith("topic /rig/imu: stamps jitter"), warnings
    np.testing.assert_array_equal(own.imu.t, regular_stamps(s.imu.t, "/rig/imu")[0])
    assert np.max(np.abs(own.imu.t - sim.sensors.imu.t - 0.004)) < 0.001
    assert all(own.load_cells[n] is s.load_cells[n] for n in s.load_cells) and own.exciter is s.exciter
    for sensors, bridged in ((own, False), (s, True)):
        w: list[str] = []
        clean_sensors(Recording(sim.rig, sensors, None, None), w)
        assert any("/rig/imu" in x and "bridged" in x for x in w) == bridged, w

def test_a_clock_with_lost_samples_is_numbered_exactly_under_jitter_of_most_of_a_period():
    """Stamps taken on a steady clock (100 Hz to 1 kHz, its rate 0.1 % off nominal), each late by a
    uniform 0 to 0.3–0.8 of a period, 0–1 % of the samples lost: every run is put back on its
    clock's instants (the mean delay kept) with each lost sample a gap of one period, and the
    warning counts them; at 0.9 of a period a run may be left as stamped, never numbered wrongly."""
    rng = np.random.default_rng(3)
    for k in range(60):
        period = rng.choice([0.001, 0.005, 0.01]) * (1 + rng.uniform(-1e-3, 1e-3))
        spread = (0.3, 0.6, 0.8, 0.9)[k % 4]
        n = int(rng.integers(300, 20000))
        true = 50.0 + period * np.arange(n)
        keep = np.ones(n, bool)
        keep[rng.choice(np.arange(1, n - 1), int(rng.integers(0, n // 100 + 1)), replace=False)] = False
        delay = rng.uniform(0.0, spread * period, n)
        out, note = regular_stamps((true + delay)[keep], "/rig/imu")
        if note is None:
            assert spread == 0.9, (k, spread, n)
            continue
        lost = int(n - keep.sum())
        assert np.max(np.abs(out - true[keep] - spread * period / 2)) < 0.05 * period, (k, spread, n)
        assert (f"{lost} sample(s) lost" in note) == (lost > 0), note


# 7. gaps ---------------------------------------------------------------------------------------
def _cut(ts, t0, t1):
    """``ts`` without its samples in [t0, t1]: a new TimeSeries."""
    m = (ts.t < t0) | (ts.t > t1)
    return TimeSeries(ts.t[m], ts.data[m])


@pytest.mark.parametrize("topic", ["imu", "c1"])
def test_gap_excluded(sim, tmp_path, topic):
    def gap(s):
        t0 = s.imu.t[0]
        if topic == "imu":
            return dataclasses.replace(s, imu=_cut(s.imu, t0 + 4.0, t0 + 6.0))
        s.load_cells[topic] = _cut(s.load_cells[topic], t0 + 4.0, t0 + 6.0)
        return s
    warnings, s, t0 = cleaned(make(sim, tmp_path, gap))
    name = "/rig/imu" if topic == "imu" else f"/rig/load_cells/{topic}"
    assert any(name in w and "gap" in w and "excluded" in w for w in warnings), warnings
    assert s.t_start - t0 > 5.9 and s.t_end == pytest.approx(sim.sensors.t_end)    # the longest clean span


def test_gap_leaves_too_little(sim, tmp_path):
    def gaps(s):
        t0 = s.imu.t[0]
        for a in (8.0, 17.0, 26.0):
            s = dataclasses.replace(s, imu=_cut(s.imu, t0 + a, t0 + a + 1.0))
        return s
    rec = make(sim, tmp_path, gaps)
    rc, _, err = run(rec)
    assert rc == 2
    assert "/rig/imu" in err and "gap" in err


# 8. saturation ----------------------------------------------------------------------------------
def assert_excluded(sim, tmp_path, edit, topic: str, reason: str) -> None:
    """The recording with ``edit`` applied (a fault at 3–4.5 s) is cleaned with a warning that a
    span of ``topic`` was excluded for ``reason``; the fit's data start after it."""
    warnings, s, t0 = cleaned(make(sim, tmp_path, edit))
    assert any(topic in w and reason in w for w in warnings), warnings
    assert s.t_start - t0 >= 4.4, s.t_start - t0


def test_saturated_load_cell(sim, tmp_path):
    def sat(s):  # the load cell jumps to its range and sticks there for 1.5 s
        c = s.load_cells["c3"]
        m = (c.t > c.t[0] + 3.0) & (c.t < c.t[0] + 4.5)
        c.data[m, 0] = 1.05 * c.data[:, 0].max()
    assert_excluded(sim, tmp_path, sat, "/rig/load_cells/c3", "saturat")


def test_load_cell_spikes_are_replaced_not_fitted(sim, tmp_path):
    """Single-sample spikes on a load cell (electrical interference: +3 kN, −2 kN, +800 N) are
    replaced by the cubic through their neighbours, with a warning naming the topic and their
    count: each replaced sample within a few of the cell's 0.5 N noise of the spike-free one (left
    in, each is thousands of it)."""
    def spikes(s):
        c = s.load_cells["c1"]
        for i, dv in zip((700, 1500, 2300), (3000.0, -2000.0, 800.0)):
            c.data[i, 0] += dv
    warnings, s, _ = cleaned(make(sim, tmp_path, spikes))
    assert any("/rig/load_cells/c1" in w and "3 single-sample spike(s)" in w for w in warnings), warnings
    at = [700, 1500, 2300]
    fixed, clean = s.load_cells["c1"].data[at, 0], sim.sensors.load_cells["c1"].data[at, 0]
    assert np.all(np.abs(fixed - clean) < 3.0), fixed - clean


def test_the_rig_model_fits_through_every_recoverable_fault_at_once(sim, tmp_path):
    """``rig-identify inertia`` (the rig model: the load cells are outputs, so a spike left in
    would be fitted) on one recording with the faults the reading and the cleaning recover: the
    IMU stamped on arrival (±4 ms), one of its messages duplicated and three lost (non-finite,
    dropped by the reader, the gap bridged by the cleaning), a load cell gone for 2 s (its span
    excluded) and three single-sample spikes on another.  Each is said in the
    warnings (on stderr too), the verdict is ``ok`` and every entry lies within 1 % and 3 σ of the
    truth."""
    rng = np.random.default_rng(11)

    def every(s):
        t = s.imu.t + rng.uniform(-0.004, 0.004, len(s.imu.t))
        k = len(t) // 3
        imu = TimeSeries(np.insert(t, k, t[k]), np.insert(s.imu.data, k, s.imu.data[k], axis=0))
        imu.data[2 * k:2 * k + 3, 0] = np.nan
        c = s.load_cells["c1"]
        for i, dv in zip((700, 1500, 2300), (3000.0, -2000.0, 800.0)):
            c.data[i, 0] += dv
        s.load_cells["c2"] = _cut(s.load_cells["c2"], imu.t[0] + 2.0, imu.t[0] + 4.0)
        return dataclasses.replace(s, imu=imu)
    rc, out, err = run(make(sim, tmp_path, every))
    assert rc == 0, err
    assert out["schema"] == "rig_identification.rig_model_result"
    w = out["warnings"]
    for topic, words in (("/rig/imu", "jitter"), ("/rig/imu", "duplicated"), ("/rig/imu", "3 sample(s) lost"),
                         ("/rig/load_cells/c2", "gap"), ("/rig/load_cells/c1", "3 single-sample spike(s)")):
        assert any(topic in x and words in x for x in w), (topic, words, w)
    assert "warning:" in err
    assert out["window"]["start_s"] > 3.9, out["window"]
    assert out["verdict"] == "ok", (out["verdict"], out["residual_level"])
    for k, c in out["truth_comparison"].items():
        assert abs(c["error_percent"]) < 1.0 and abs(c["error_sigma"]) < 3.0, (k, c)


def test_noise_free_steps_are_not_saturation(sim):
    """A noise-free stream that holds a value exactly (a simulated stepped force, the thesis's
    case studies 1–9) is not a saturated sensor; the same run of identical samples in a
    noisy channel is."""
    from rig_identification.io.quality import find_bad_spans
    s = copy.deepcopy(sim.sensors)
    t = s.exciter.t
    step = np.where((t > t[0] + 5) & (t < t[0] + 8), 200.0, 0.0)
    s = dataclasses.replace(s, exciter=TimeSeries(t, np.column_stack([step, np.zeros(len(t))])))
    assert not [b for b in find_bad_spans(sim.rig, s) if "exciter" in b.topic]
    noisy = step + 0.5 * np.random.default_rng(0).standard_normal(len(t))
    noisy[(t > t[0] + 5) & (t < t[0] + 8)] = noisy.max()
    s = dataclasses.replace(s, exciter=TimeSeries(t, np.column_stack([noisy, 0.5 * np.random.default_rng(1)
                                                                      .standard_normal(len(t))])))
    spans = [b for b in find_bad_spans(sim.rig, s) if "exciter" in b.topic]
    assert len(spans) == 1 and "saturated" in spans[0].reason
    assert spans[0].t0 == pytest.approx(t[0] + 5, abs=0.02) and spans[0].t1 == pytest.approx(t[0] + 8, abs=0.02)


# 9. slack cable ------------------------------------------------------------------------------
def test_slack_cable(sim, tmp_path):
    def slack(s):
        c = s.load_cells["c2"]
        t0 = c.t[0]
        m = (c.t > t0 + 3.0) & (c.t < t0 + 4.5)
        c.data[m, 0] = np.abs(np.random.default_rng(0).normal(0, 2.0, m.sum()))
    assert_excluded(sim, tmp_path, slack, "/rig/load_cells/c2", "slack")


# 10. rig.yaml contradicting the bag ------------------------------------------------------------
def _edit_rig(rec, fn):
    d = yaml.safe_load((rec / "rig.yaml").read_text())
    fn(d)
    (rec / "rig.yaml").write_text(yaml.safe_dump(d))


def test_rig_cable_not_in_bag(sim, tmp_path):
    rec = make(sim, tmp_path)
    _edit_rig(rec, lambda d: d["cables"][1].update(name="c9"))
    rc, _, err = run(rec)
    assert rc == 2
    assert "c9" in err


def test_bag_cable_not_in_rig(sim, tmp_path):
    rec = make(sim, tmp_path)
    _edit_rig(rec, lambda d: d["cables"].pop())
    rc, _, err = run(rec)
    assert rc == 2
    assert "/rig/load_cells/c3" in err and "rig.yaml" in err


def test_lengths_in_mm(sim, tmp_path):
    rec = make(sim, tmp_path)

    def mm(d):
        for c in d["cables"]:
            c["length"] *= 1000.0
    _edit_rig(rec, mm)
    rc, _, err = run(rec)
    assert rc == 2
    assert "units" in err and "rig.yaml" in err


def test_tensions_in_kN(sim, tmp_path):
    def kn(s):
        for n, c in s.load_cells.items():
            s.load_cells[n] = TimeSeries(c.t, c.data / 1000.0)
    rec = make(sim, tmp_path, kn)
    rc, _, err = run(rec)
    assert rc == 2
    assert "units" in err and "tension" in err


# 11. static recording ----------------------------------------------------------------------------
def test_static_recording(sim, tmp_path):
    from rig_identification.model.experiment import load_experiment
    from rig_identification.model.simulator import simulate
    exp = load_experiment(str(REPO / "config/rigs/default.yaml")).with_overrides(duration=30.0, static="baseline")
    st = simulate(exp)
    rec = write_recording(tmp_path / "static", sim.rig, st.sensors, st.truth)  # sim.rig: with the CG
    rc, _, err = run(rec)
    assert rc == 2
    assert "did not move" in err and "static recording" in err


def test_a_motion_the_gyro_does_not_see_but_the_tensions_do_is_fitted_not_refused(sim):
    """The shaken default rig with its gyro's motion taken out (white noise of the gyro's σ
    left: a motion within the gyro's noise, as on bench_any_rig's 21057) is not a static recording:
    its tensions swing far beyond their noise, and the load cells are outputs of the fit.  With the
    tensions' motion taken out too (each its mean plus white noise) it is refused, naming both."""
    rng = np.random.default_rng(3)
    s = sim.sensors
    imu = s.imu.data.copy()
    imu[:, :3] = rng.normal(0.0, white_sigma(imu[:, :3]), imu[:, :3].shape)
    quiet_gyro = dataclasses.replace(s, imu=TimeSeries(s.imu.t, imu))
    rec = Recording(sim.rig, quiet_gyro, sim.truth, None)
    check_motion(rec, quiet_gyro)
    still = {n: TimeSeries(c.t, c.data.mean() + rng.normal(0.0, white_sigma(c.data), c.data.shape))
             for n, c in s.load_cells.items()}
    static = dataclasses.replace(quiet_gyro, load_cells=still)
    with pytest.raises(RecordingError, match=r"did not move .*gyro RMS.*the tensions at most"):
        check_motion(Recording(sim.rig, static, sim.truth, None), static)


def test_missing_paths_are_named_at_once(tmp_path):
    """A path that does not exist is refused first, naming it: exit 2, one line, before any bag is
    read or any heavy module loaded (the other recording given is not even read)."""
    missing = tmp_path / "no_such_recording"
    ref = REPO.parent / "shared" / "recordings" / "visible_case16_clean"
    cases = [["inertia", str(missing)], ["inertia", str(ref), str(missing)], ["diagnose", str(missing)],
             ["modes", str(missing)], ["plan", str(missing), "--inertia", "1", "1", "1", "0", "0", "0"],
             ["inertia", str(ref), "--yaml", str(missing / "out.yaml")],
             ["inertia", str(ref), "--cg", str(tmp_path / "cg.json")],
             ["cg", str(missing), str(ref)]]    # last: its parser (cli.cg) loads scipy
    code = ("import json, sys\nfrom rig_identification.cli.main import identify_main\n"
            f"codes = [identify_main(a) for a in {cases[:-1]!r}]\n"
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('scipy', 'rosbags', 'matplotlib'))\n"
            f"codes.append(identify_main({cases[-1]!r}))\n"
            "print(json.dumps({'codes': codes, 'heavy': heavy}))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert "Traceback" not in p.stderr, p.stderr
    res = json.loads(p.stdout)
    assert res["codes"] == [2] * len(cases) and res["heavy"] == [], res
    lines = p.stderr.splitlines()
    assert len(lines) == len(cases) and all(ln.startswith("rig-identify: error: ") for ln in lines), lines
    for ln, what in zip(lines, [missing] * 5 + [missing / "out.yaml", tmp_path / "cg.json", missing]):
        assert str(what) in ln, ln
    assert "no such file or directory" in lines[0] and "cannot write it" in lines[5]


def test_outputs_need_an_existing_folder(tmp_path, capsys):
    """One rule for every output, file or folder (--yaml, --write-rig, --report): its folder must
    exist.  Refused before any work, naming the path, the missing folder and the option; nothing
    is created (`--report /nope/dir/x.html` used to create /nope/dir)."""
    ref = str(REPO.parent / "shared" / "recordings" / "visible_case16_clean")
    missing = tmp_path / "nope" / "dir"
    cases = [(["inertia", ref, "--report", str(missing / "x.html")], "--report"),
             (["inertia", ref, "--yaml", str(missing / "x.yaml")], "--yaml"),
             (["diagnose", ref, "--report", str(missing / "report")], "--report"),
             (["cg", ref, ref, "--write-rig", str(missing / "rig.yaml")], "--write-rig")]
    for argv, option in cases:
        assert identify_main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("rig-identify: error: "), err
        assert argv[-1] in err[0] and f"no folder {missing}" in err[0] and f"({option})" in err[0], err
    assert not (tmp_path / "nope").exists()
    # the other way round: a file where a folder goes, a folder where a file goes
    plain = tmp_path / "notes.txt"
    plain.write_text("keep me")
    assert identify_main(["inertia", ref, "--report", str(plain)]) == 2
    assert f"{plain}: is not a folder (--report takes a folder)" in capsys.readouterr().err
    assert identify_main(["inertia", ref, "--yaml", str(tmp_path)]) == 2
    assert f"{tmp_path}: is a folder (--yaml takes a file)" in capsys.readouterr().err
    assert plain.read_text() == "keep me"
