"""Live CG capture (core of the identifier node's CG services) on the reference static pair,
fed sample by sample as the node would; it agrees with `rig-identify cg` on the recordings."""
import numpy as np
import pytest
from conftest import recording

from rig_identification.io.recording import read_recording
from rig_identification.statics import StaticsError, StaticState, estimate_cg
from rig_identification.statics.capture import CgSession


def feed(session, sensors, shift):
    events = [(t + shift, "imu", i) for i, t in enumerate(sensors.imu.t)]
    for n, s in sensors.load_cells.items():
        events += [(t + shift, n, i) for i, t in enumerate(s.t)]
    events += [(t + shift, "exc", i) for i, t in enumerate(sensors.exciter.t)]
    events += [(t + shift, "incl", i) for i, t in enumerate(sensors.inclinometer.t)]
    for t, kind, i in sorted(events):
        if kind == "imu":
            session.add_imu(t, sensors.imu.data[i, :3], sensors.imu.data[i, 3:])
        elif kind == "exc":
            session.add_exciter(t, *sensors.exciter.data[i])
        elif kind == "incl":
            session.add_inclinometer(t, sensors.inclinometer.data[i])
        else:
            session.add_tension(kind, t, sensors.load_cells[kind].data[i, 0])


def test_live_capture_matches_offline():
    base = read_recording(recording("visible_case16_static/static_baseline"))
    dummy = read_recording(recording("visible_case16_static/static_dummy"))
    session = CgSession(base.rig, seconds=10.0)
    with pytest.raises(StaticsError, match="capture the baseline and dummy"):
        session.estimate()
    feed(session, base.sensors, 0.0)
    session.capture("baseline")
    feed(session, dummy.sensors, 60.0)  # the dummy is fixed a minute later
    session.capture("dummy")
    live = session.estimate()
    offline = estimate_cg(base.rig, StaticState.from_recording(base, label="baseline"),
                          StaticState.from_recording(dummy, label="dummy"))
    np.testing.assert_allclose(live.center_of_gravity, offline.center_of_gravity, atol=2e-4)
    truth = np.asarray(base.truth["center_of_gravity"])
    assert np.all(np.abs(live.center_of_gravity - truth) < 3 * live.center_of_gravity_std + 1e-4)


def test_capture_needs_data():
    base = read_recording(recording("visible_case16_static/static_baseline"))
    session = CgSession(base.rig)
    with pytest.raises(StaticsError, match="/rig/imu"):
        session.capture("baseline")
