"""Fuzz the input readers (issue 6): rig.yaml loader and bag reader raise only RigError/RecordingError."""
import copy
import shutil
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig_identification.io.recording import RecordingError, read_sensor_data
from rig_identification.io.recording_writer import write_recording
from rig_identification.io.rig import RigError, load_rig, rig_from_dict

REPO = Path(__file__).resolve().parents[1]
SETTINGS = settings(max_examples=100, deadline=None, suppress_health_check=list(HealthCheck))

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                    st.text(max_size=8))
values = st.recursive(scalars, lambda ch: st.one_of(st.lists(ch, max_size=4),
                                                   st.dictionaries(st.text(max_size=8), ch, max_size=4)),
                      max_leaves=12)


def _valid_rig_dict(tmp):
    from rig_identification.io.rig import dump_rig
    from rig_identification.model.experiment import load_experiment
    return yaml.safe_load(dump_rig(load_experiment(str(REPO / "config/rigs/default.yaml")).rig))


VALID = None


def valid():
    global VALID
    if VALID is None:
        VALID = _valid_rig_dict(None)
    return VALID


def _paths(d, prefix=()):
    yield prefix
    if isinstance(d, dict):
        for k, v in d.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from _paths(v, prefix + (i,))


@SETTINGS
@given(values)
def test_rig_from_random_dict(d):
    try:
        rig_from_dict(d)
    except RigError:
        pass


@SETTINGS
@given(st.data())
def test_rig_from_mutated_dict(data):
    d = copy.deepcopy(valid())
    paths = [p for p in _paths(d) if p]
    for _ in range(data.draw(st.integers(1, 3))):
        p = data.draw(st.sampled_from(paths))
        parent = d
        try:
            for k in p[:-1]:
                parent = parent[k]
            if data.draw(st.booleans()):
                parent[p[-1]] = data.draw(values)
            else:
                del parent[p[-1]]
        except (KeyError, IndexError, TypeError):
            pass
    try:
        rig_from_dict(d)
    except RigError:
        pass


@SETTINGS
@given(st.binary(max_size=400))
def test_load_rig_random_bytes(tmp_path_factory, b):
    p = tmp_path_factory.mktemp("rig") / "rig.yaml"
    p.write_bytes(b)
    try:
        load_rig(p)
    except RigError:
        pass


@pytest.fixture(scope="module", params=["mcap", "sqlite3"])
def small_bag(request, tmp_path_factory):
    import dataclasses

    from rig_identification.model.experiment import load_experiment
    from rig_identification.model.simulator import simulate
    exp = load_experiment(str(REPO / "config/rigs/default.yaml")).with_overrides(duration=2.0)
    exp = dataclasses.replace(exp, sensors=dataclasses.replace(
        exp.sensors, rates={k: min(v, 20.0) for k, v in exp.sensors.rates.items()}))
    r = simulate(exp)
    rec = write_recording(tmp_path_factory.mktemp("bag") / "rec", r.rig, r.sensors, None, storage=request.param)
    return rec / "bag", list(r.rig.cable_names)


@SETTINGS
@given(data=st.data())
def test_read_corrupted_bag(small_bag, tmp_path_factory, data):
    bag, names = small_bag
    dst = tmp_path_factory.mktemp("fuzz") / "bag"
    shutil.copytree(bag, dst)
    files = sorted(f for f in dst.iterdir() if f.is_file())
    f = data.draw(st.sampled_from(files))
    b = bytearray(f.read_bytes())
    if data.draw(st.booleans()):
        b = b[: data.draw(st.integers(0, len(b)))]
    for _ in range(data.draw(st.integers(0, 20))):
        if b:
            i = data.draw(st.integers(0, len(b) - 1))
            b[i] = data.draw(st.integers(0, 255))
    f.write_bytes(bytes(b))
    try:
        read_sensor_data(dst, names)
    except RecordingError:
        pass
