"""rig.yaml loader: the reference recordings load; wrong or missing fields name the field."""
import copy
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import REPO, recording, run_cli

from rig_identification.cli.plan import force_limit
from rig_identification.io.rig import RigError, dump_rig, load_rig, rig_from_dict
from rig_identification.model.experiment import load_experiment


@pytest.fixture
def rig_dict():
    return yaml.safe_load((recording("visible_case16_clean") / "rig.yaml").read_text())


def test_reference_rig_loads(rig_dict):
    rig = rig_from_dict(rig_dict, "rig.yaml")
    assert rig.cable_names == ["c0", "c1", "c2", "c3"]
    assert rig.mass == 1810.0
    np.testing.assert_allclose(rig.body_anchors[0], [-0.8, -1.25, 1.29])
    assert rig.cable_stiffness.tolist() == [np.inf] * 4


def test_name_and_output_axes_are_optional_and_kept(rig_dict, tmp_path):
    """rig.yaml's optional ``name`` (the report shows it) and ``output_axes`` (the default of
    rig-identify inertia --axes) are read, written back by dump_rig (so --write-rig copies keep
    them) and absent by default."""
    from rig_identification.report.folder import rig_label
    plain = rig_from_dict(rig_dict, "rig.yaml")
    assert plain.name is None and plain.output_axes is None
    assert "name" not in plain.to_dict() and "output_axes" not in plain.to_dict()
    assert rig_label(plain) == "rig.yaml"
    d = copy.deepcopy(rig_dict) | {"name": "Hall 3 rig, 4 cables", "output_axes": "sae"}
    d["body"]["vehicle"] = {"front": "+y", "top": "+z"}      # vehicle axes need the vehicle's orientation
    rig = rig_from_dict(d, "rig.yaml")
    assert rig.name == "Hall 3 rig, 4 cables" and rig.output_axes == "sae"
    assert rig_label(rig) == "Hall 3 rig, 4 cables (rig.yaml)"
    p = tmp_path / "rig.yaml"
    p.write_text(dump_rig(rig.with_cg([0.01, 0.0, 0.0])))
    back = load_rig(p)
    assert back.name == rig.name and back.output_axes == "sae" and back.vehicle == rig.vehicle
    assert list(yaml.safe_load(p.read_text()))[:2] == ["name", "output_axes"]


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


# --- fields rig.yaml does not have, geometry no rig can have ---------------------------------------

@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["body"].__setitem__("centre_of_gravity", [0, 0, 0]),
     "unknown field body.centre_of_gravity (did you mean body.center_of_gravity?)"),
    (lambda d: d.__setitem__("cable", d.pop("cables")), "unknown field cable (did you mean cables?)"),
    (lambda d: d["cables"][2].__setitem__("lenght", d["cables"][2].pop("length")),
     "unknown field cables[2].lenght (did you mean cables[2].length?)"),
    (lambda d: d["imu"].__setitem__("frame_id", "imu"), "unknown field imu.frame_id (known: position, rpy)"),
    (lambda d: d["inclinometer"].__setitem__("position", [0, 0, 0]),
     "unknown field inclinometer.position (an inclinometer's reading does not depend on where it sits"),
    (lambda d: d.__setitem__("dummy_mass", {"mass": 50.0, "positon": [0, 0, 0]}),
     "unknown field dummy_mass.positon (did you mean dummy_mass.position?)"),
    (lambda d: d.__setitem__("gravity", float("nan")), "field gravity must be finite"),
    (lambda d: d["cables"][1].__setitem__("ceiling_anchor", [4.0, float("inf"), 0.0]),
     "field cables[1].ceiling_anchor[1] must be finite"),
    (lambda d: d.__setitem__("dummy_mass", {"mass": 0.0, "position": [0, 0, 0]}), "field dummy_mass.mass must be > 0"),
    (lambda d: d["body"].__setitem__("mass", 0), "field body.mass must be > 0"),
    (lambda d: d.__setitem__("nmae", "rig A"), "unknown field nmae (did you mean name?)"),
    (lambda d: d.__setitem__("output_axis", "sae"), "unknown field output_axis (did you mean output_axes?)"),
    (lambda d: d.__setitem__("output_axes", "SAE"),
     "field output_axes must be one of body, sae, iso8855 (the axes rig-identify prints and exports in by default), "
     "got 'SAE' (did you mean sae?)"),
    (lambda d: d.__setitem__("output_axes", "sae"), "field output_axes: sae (vehicle axes) needs field body.vehicle"),
    (lambda d: d["body"].__setitem__("vehicle", {"front": "forward", "top": "+z"}),
     "field body.vehicle.front must be one of +x, -x, +y, -y, +z, -z"),
    (lambda d: d["body"].__setitem__("vehicle", {"front": "+z", "top": "+z"}),
     "field body.vehicle: front +z and top +z lie on the same body axis"),
    (lambda d: d.__setitem__("name", ["rig", "A"]), "field name must be a one-line text"),
    (lambda d: d.__setitem__("name", "  "), "field name must be a one-line text"),
])
def test_unknown_or_impossible_field_is_named(rig_dict, mutate, message):
    d = copy.deepcopy(rig_dict)
    mutate(d)
    with pytest.raises(RigError) as e:
        rig_from_dict(d, "my_rig.yaml")
    assert str(e.value).startswith("my_rig.yaml: ") and message in str(e.value), str(e.value)


def test_ceiling_anchor_in_millimetres_is_refused(rig_dict):
    d = copy.deepcopy(rig_dict)
    d["cables"][1]["ceiling_anchor"] = [4000.0, 0.0, 0.0]          # mm, the others in m
    with pytest.raises(RigError) as e:
        rig_from_dict(d, "my_rig.yaml")
    msg = str(e.value)
    assert "cables c0 and c1 cannot both be taut" in msg and "cables[0], cables[1]" in msg and "units" in msg
    assert "their ceiling anchors' distance is 4000 m" in msg


def test_cable_length_in_millimetres_is_refused(rig_dict):
    d = copy.deepcopy(rig_dict)
    d["cables"][3]["length"] *= 1000.0
    with pytest.raises(RigError) as e:
        rig_from_dict(d, "my_rig.yaml")
    assert "cable c3's length is 2515 m" in str(e.value) and "cables[0], cables[3]" in str(e.value)


def _scaled(d: dict, factor: float) -> dict:
    """rig.yaml with every length in it multiplied by ``factor`` (metres to millimetres: 1000)."""
    d = copy.deepcopy(d)
    for c in d["cables"]:
        c["ceiling_anchor"] = [factor * x for x in c["ceiling_anchor"]]
        c["body_anchor"] = [factor * x for x in c["body_anchor"]]
        c["length"] *= factor
    for key in ("imu", "exciter"):
        d[key]["position"] = [factor * x for x in d[key]["position"]]
    d["body"]["center_of_gravity"] = [factor * x for x in d["body"]["center_of_gravity"]]
    return d


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(_scaled(d, 1000.0)), "the ceiling anchors span 6560 m"),
    (lambda d: d["body"].update(mass=1810e3), "body.mass = 1.81e+06 kg"),
    (lambda d: d["imu"].update(rpy=[0.0, 0.0, 90.0]), "imu.rpy"),
    (lambda d: d["cables"][2].update(stiffness=5e3), "cables[2].stiffness = 5000 N/m would stretch cable c2"),
    (lambda d: d["exciter"].update(position=[-800.0, -1250.0, -460.0]), "exciter.position"),
])
def test_rig_in_other_units_is_refused(rig_dict, mutate, message):
    """The whole rig in millimetres passes the reach check (every side scaled alike) and ran
    806 s to an Ixx of 3·10⁶ kg·m²: it is refused at load, with the unit it probably is."""
    d = copy.deepcopy(rig_dict)
    mutate(d)
    with pytest.raises(RigError) as e:
        rig_from_dict(d, "my_rig.yaml")
    msg = str(e.value)
    assert msg.startswith("my_rig.yaml: field ") and message in msg, msg
    assert any(u in msg for u in ("millimetres?", "grams?", "degrees?", "N/mm?")), msg


def test_largest_plausible_rig_loads(rig_dict):
    """A rig ten times the reference (cables 20–25 m, ceiling anchors 66 m apart) is past the limit only
    where a span exceeds 30 m; at three times it loads."""
    rig_from_dict(_scaled(rig_dict, 3.0))
    with pytest.raises(RigError, match="span"):
        rig_from_dict(_scaled(rig_dict, 10.0))


def test_reach_is_the_polygon_inequality(rig_dict):
    """A cable cannot be taut while longer than the way round through another taut cable:
    L0 <= |A0 - Aj| + Lj + |B0 - Bj| for every j (+2 % for the stretch)."""
    rig = rig_from_dict(copy.deepcopy(rig_dict))
    c0 = rig.cables[0]
    longest = min(np.linalg.norm(c0.ceiling_anchor - c.ceiling_anchor) + c.length
                  + np.linalg.norm(c0.body_anchor - c.body_anchor) for c in rig.cables[1:])
    for factor, ok in ((1.01, True), (1.03, False)):
        d = copy.deepcopy(rig_dict)
        d["cables"][0]["length"] = factor * longest
        if ok:
            rig_from_dict(d)                      # at the limit, stretched: still a rig
        else:
            with pytest.raises(RigError, match="cable c0's length is .* cannot|cannot both be taut"):
                rig_from_dict(d)


def test_every_rig_of_the_repository_loads():
    """The reference recordings' rig.yaml and every experiment file's rig section still load."""
    rigs = sorted(Path(recording("visible_case16_clean")).parent.glob("**/rig.yaml"))
    experiments = sorted((REPO / "config" / "cases").glob("*.yaml")) + sorted((REPO / "config" / "rigs").glob("*.yaml"))
    assert len(rigs) >= 5 and len(experiments) >= 19
    for p in rigs:
        assert len(load_rig(p).cables) >= 3
    for p in experiments:
        assert load_experiment(p).rig.mass > 0


def test_survey_is_read_checked_and_written_back(rig_dict):
    """rig.yaml ``survey``: the lab's σ of its geometry, scale and load cells; absent, the 1 mm
    defaults, 0.1 % of the mass and 0.1 % of a gain; a σ in millimetres or per cents is refused."""
    plain = rig_from_dict(rig_dict, "rig.yaml")
    assert plain.survey.anchors == plain.survey.lengths == plain.survey.dummy_position == 1e-3
    assert plain.survey.load_cell_gain == 1e-3
    assert plain.survey.mass_std(1810.0) == pytest.approx(1.81) and "survey" not in plain.to_dict()
    d = copy.deepcopy(rig_dict) | {"survey": {"anchors": 0.0005, "lengths": 0.002, "mass": 0.5,
                                              "load_cell_gain": 0.0}}
    rig = rig_from_dict(d, "rig.yaml")
    assert (rig.survey.anchors, rig.survey.lengths, rig.survey.dummy_position) == (0.0005, 0.002, 1e-3)
    assert rig.survey.load_cell_gain == 0.0
    assert rig.survey.mass_std(1810.0) == 0.5
    assert rig_from_dict(rig.to_dict()).survey == rig.survey
    for bad, msg in (({"anchors": 1.0}, "survey.anchors = 1 m is more than 10 cm"),
                     ({"lengths": -0.001}, "survey.lengths must be >= 0"),
                     ({"mass": 0.0}, "survey.mass must be > 0"), ({"anchor": 0.001}, "unknown field survey.anchor"),
                     ({"load_cell_gain": 1.0}, "survey.load_cell_gain = 1 is more than 10 %")):
        with pytest.raises(RigError, match=msg.replace(".", r"\.")):
            rig_from_dict(copy.deepcopy(rig_dict) | {"survey": bad}, "rig.yaml")


def test_cg_takes_its_geometry_sigma_from_the_rig_survey(tmp_path):
    """``cg`` on a static pair whose rig.yaml says the geometry is exact gives the σ of
    --anchor-std 0 --length-std 0 --dummy-position-std 0 on the same pair, and prints it."""
    pair = []
    for name in ("static_baseline", "static_dummy"):
        src = recording("visible_case16_static") / name
        dst = tmp_path / name
        shutil.copytree(src, dst)
        d = yaml.safe_load((dst / "rig.yaml").read_text())
        d["survey"] = {"anchors": 0.0, "lengths": 0.0, "dummy_position": 0.0}
        (dst / "rig.yaml").write_text(yaml.safe_dump(d))
        pair.append(dst)
    code, out, err = run_cli("cg", *pair, "--json", "-q")
    assert code == 0, err
    exact = [recording("visible_case16_static") / n for n in ("static_baseline", "static_dummy")]
    code2, out2, err2 = run_cli("cg", *exact, "--json", "-q", "--anchor-std", "0", "--length-std", "0",
                                "--dummy-position-std", "0")
    code3, out3, _ = run_cli("cg", *exact, "--json", "-q")
    assert code2 == 0 and code3 == 0, err2
    a, b, c = (json.loads(o)["center_of_gravity_std"] for o in (out, out2, out3))
    np.testing.assert_allclose(a, b, rtol=1e-9)
    assert c[2] > 5 * a[2]                       # the 1 mm default survey dominates the height's σ


def test_exciter_max_force_is_read_and_bounds_the_plan(rig_dict):
    """rig.yaml ``exciter.max_force`` (N) is read and written back; ``plan`` takes it as its force
    limit unless --max-force says otherwise, and says where the limit came from."""
    d = copy.deepcopy(rig_dict)
    d["exciter"]["max_force"] = 150.0
    rig = rig_from_dict(d, "rig.yaml")
    assert rig.exciter.max_force == 150.0 and rig_from_dict(rig.to_dict()).exciter.max_force == 150.0
    assert rig_from_dict(rig_dict).exciter.max_force is None
    with pytest.raises(RigError, match="exciter.max_force must be > 0"):
        rig_from_dict(copy.deepcopy(rig_dict) | {"exciter": rig_dict["exciter"] | {"max_force": 0}}, "rig.yaml")
    assert force_limit(150.0, rig) == "force ≤ 150 N (rig.yaml exciter.max_force)"
    assert force_limit(120.0, rig) == "force ≤ 120 N (--max-force)"
    assert force_limit(float("inf"), rig) == "force not limited (--max-force inf)"
    assert force_limit(float("inf"), rig_from_dict(rig_dict)).startswith(
        "force not limited (rig.yaml gives no exciter.max_force")
