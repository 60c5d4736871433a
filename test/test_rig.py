"""rig.yaml loader: the reference recordings load; wrong or missing fields name the field."""
import copy

import numpy as np
import pytest
import yaml

from rig_identification.rig import RigError, dump_rig, load_rig, rig_from_dict

from conftest import recording


@pytest.fixture
def rig_dict():
    return yaml.safe_load((recording("visible_case16_clean") / "rig.yaml").read_text())


def test_reference_rig_loads(rig_dict):
    rig = rig_from_dict(rig_dict, "rig.yaml")
    assert rig.cable_names == ["c0", "c1", "c2", "c3"]
    assert rig.mass == 1810.0
    np.testing.assert_allclose(rig.body_anchors[0], [-0.8, -1.25, 1.29])
    assert rig.cable_stiffness.tolist() == [np.inf] * 4


def test_round_trip(rig_dict, tmp_path):
    rig = rig_from_dict(rig_dict)
    p = tmp_path / "rig.yaml"
    p.write_text(dump_rig(rig))
    back = load_rig(p)
    np.testing.assert_array_equal(back.ceiling_anchors, rig.ceiling_anchors)
    np.testing.assert_array_equal(back.center_of_gravity, rig.center_of_gravity)


def test_yaml12_float_stiffness(rig_dict, tmp_path):
    # PyYAML (YAML 1.1) reads "5.0e6" as a string; the spec writes it that way
    text = (recording("visible_case16_clean") / "rig.yaml").read_text().replace(
        "  length: 1.9663672088396917", "  length: 1.9663672088396917\n  stiffness: 5.0e6")
    p = tmp_path / "rig.yaml"
    p.write_text(text)
    assert load_rig(p).cables[0].stiffness == 5.0e6


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d.pop("gravity"), "gravity"),
    (lambda d: d["cables"].pop() and d["cables"].pop(), "cables"),
    (lambda d: d["cables"][1].pop("length"), "cables[1].length"),
    (lambda d: d["cables"][2].__setitem__("body_anchor", [1, 2]), "cables[2].body_anchor"),
    (lambda d: d["cables"][0].__setitem__("name", "C 0"), "cables[0].name"),
    (lambda d: d["cables"][3].__setitem__("name", "c0"), "cables[3].name"),
    (lambda d: d["body"].__setitem__("mass", -3), "body.mass"),
    (lambda d: d["imu"].pop("position"), "imu.position"),
    (lambda d: d["cables"][0].__setitem__("stiffness", "stiff"), "cables[0].stiffness"),
    (lambda d: d.__setitem__("gravity", 9806.65), "gravity"),
])
def test_bad_field_is_named(rig_dict, mutate, field):
    d = copy.deepcopy(rig_dict)
    mutate(d)
    with pytest.raises(RigError) as e:
        rig_from_dict(d, "my_rig.yaml")
    assert "my_rig.yaml" in str(e.value) and field in str(e.value)


def test_unreadable_file(tmp_path):
    with pytest.raises(RigError, match="cannot read"):
        load_rig(tmp_path / "none.yaml")
    (tmp_path / "bad.yaml").write_text("cables: [\n")
    with pytest.raises(RigError, match="not valid YAML"):
        load_rig(tmp_path / "bad.yaml")
