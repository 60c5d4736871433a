"""The CG hand-over from the static to the dynamic experiment (rig day).

``rig-identify cg BASELINE DUMMY --write-rig OUT.yaml`` writes the recordings' rig.yaml with
body.center_of_gravity set (comment lines: date, σ, sources), refuses an existing OUT unless
--force, never a recording's own rig.yaml; ``--json`` has a schema, a version and units, and
a saved copy is read back by ``statics.handover.load_cg_result`` (for ``rig-identify inertia --cg``),
whose errors name the file and the field.
"""
import contextlib
import io
import json

import numpy as np
import pytest
import yaml
from conftest import recording

from rig_identification.cli.main import identify_main
from rig_identification.io.rig import load_rig
from rig_identification.statics import CG_RESULT_SCHEMA, CG_RESULT_SCHEMA_VERSION, StaticsError
from rig_identification.statics.handover import CgResultError, load_cg_result

BASE = recording("visible_case16_static/static_baseline")
DUMMY = recording("visible_case16_static/static_dummy")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One `rig-identify cg --json --write-rig`: (exit code, JSON, written path, the folder)."""
    out = tmp_path_factory.mktemp("handover")
    rig = out / "rig_with_cg.yaml"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = identify_main(["cg", str(BASE), str(DUMMY), "--json", "--write-rig", str(rig)])
    (out / "cg.json").write_text(buf.getvalue())
    return code, json.loads(buf.getvalue()), rig, out


def test_write_rig_is_the_recordings_rig_with_the_cg(run):
    code, j, path, _ = run
    assert code == 0 and j["written_rig"] == str(path)
    new, old = load_rig(path), load_rig(BASE / "rig.yaml")
    assert old.center_of_gravity is None
    np.testing.assert_array_equal(new.center_of_gravity, j["center_of_gravity"])      # exactly the estimate
    d_new, d_old = new.to_dict(), old.to_dict()
    d_new["body"].pop("center_of_gravity")
    assert d_new == d_old                                                              # everything else as recorded
    text = path.read_text()
    head = [line for line in text.splitlines() if line.startswith("#")]
    assert any("rig-identify cg on " + j["created"] in line for line in head)
    sd = ", ".join(f"{x * 1e3:.2f}" for x in j["center_of_gravity_std"])
    assert any(f"σ {sd} mm" in line for line in head)
    assert any(str(BASE) in line and str(DUMMY) in line for line in head)
    assert any(line.startswith("# rig description") for line in head)                 # the source's own comment
    assert not list(path.parent.glob(".rig_with_cg.yaml.*"))                           # no temporary left


def test_write_rig_refuses_to_overwrite(run, capsys):
    _, _, path, _ = run
    before = path.read_text()
    assert identify_main(["cg", str(BASE), str(DUMMY), "--write-rig", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "--force" in err and len(err.strip().splitlines()) == 1
    assert path.read_text() == before
    # a recording's own rig.yaml: never, even with --force
    assert identify_main(["cg", str(BASE), str(DUMMY), "--write-rig", str(BASE / "rig.yaml"), "--force"]) == 2
    assert "own rig.yaml" in capsys.readouterr().err
    assert load_rig(BASE / "rig.yaml").center_of_gravity is None


def test_write_rig_force_replaces(tmp_path, capsys):
    path = tmp_path / "rig.yaml"
    path.write_text("old\n")
    assert identify_main(["cg", str(BASE), str(DUMMY), "--write-rig", str(path), "--force",
                          "--anchor-std", "0.5"]) == 0
    out = capsys.readouterr().out
    assert f"wrote {path}" in out and "anchors 0.5 mm" in out
    assert load_rig(path).center_of_gravity is not None and "anchors 0.5 mm" in path.read_text()


def test_json_schema_units_and_both_sigmas(run):
    _, j, _, _ = run
    assert j["schema"] == CG_RESULT_SCHEMA and j["schema_version"] == CG_RESULT_SCHEMA_VERSION
    assert j["frame"] == "body"
    u = j["units"]
    assert u["center_of_gravity"] == "m" and u["center_of_gravity_std_noise"] == "m" and u["mass"] == "kg"
    assert u["center_of_gravity_covariance"] == "m^2" and u["cable_stiffness"] == "N/m"
    assert len(j["center_of_gravity_std_noise"]) == 3
    assert all(a > 10 * b for a, b in zip(j["center_of_gravity_std"][2:], j["center_of_gravity_std_noise"][2:]))
    unc = j["uncertainty"]
    assert unc["geometry_std"] == {"anchors": 1e-3, "cable_lengths": 1e-3, "dummy_position": 1e-3, "dummy_mass": 0.0}
    total = np.sqrt(sum(np.square(v) for v in unc["budget"].values()))
    np.testing.assert_allclose(total, j["center_of_gravity_std"], rtol=1e-6)
    assert j["validation"]["verdict"] == "ok" and j["baseline"] == str(BASE)


def test_load_cg_result_round_trip(run):
    _, j, _, folder = run
    r = load_cg_result(folder / "cg.json")
    np.testing.assert_array_equal(r.center_of_gravity, j["center_of_gravity"])
    np.testing.assert_array_equal(r.center_of_gravity_std, j["center_of_gravity_std"])
    np.testing.assert_array_equal(r.center_of_gravity_std_noise, j["center_of_gravity_std_noise"])
    assert r.covariance.shape == (3, 3) and r.mass == 1810.0 and r.verdict == "ok"
    assert r.schema_version == CG_RESULT_SCHEMA_VERSION and r.source == str(folder / "cg.json")
    # a file from before the schema field (the older --json output) is still read
    old = {k: j[k] for k in ("center_of_gravity", "center_of_gravity_std", "frame", "mass")}
    p = folder / "old.json"
    p.write_text(json.dumps(old))
    r0 = load_cg_result(p)
    assert r0.schema_version == 0 and r0.center_of_gravity_std_noise is None
    np.testing.assert_array_equal(r0.center_of_gravity, j["center_of_gravity"])


@pytest.mark.parametrize("edit, field", [
    (lambda d: d.pop("center_of_gravity"), "missing field center_of_gravity"),
    (lambda d: d.__setitem__("center_of_gravity", [0.1, 0.2]), "field center_of_gravity must be a list of 3"),
    (lambda d: d.__setitem__("center_of_gravity_std", [1e-3, 0.0, 1e-3]), "field center_of_gravity_std[1] must be > 0"),
    (lambda d: d.__setitem__("center_of_gravity", [0.1, "x", 0.2]), "field center_of_gravity must be a list of 3"),
    (lambda d: d.__setitem__("frame", "world"), "field frame"),
    (lambda d: d.__setitem__("schema", "rig_identification.inertia_result"), "field schema"),
    (lambda d: d.__setitem__("schema_version", 99), "field schema_version is 99"),
    (lambda d: d.__setitem__("center_of_gravity_covariance", [[1, 0], [0, 1]]), "field center_of_gravity_covariance"),
    (lambda d: d.__setitem__("mass", -3), "field mass"),
])
def test_load_cg_result_errors_name_file_and_field(run, tmp_path, edit, field):
    _, j, _, _ = run
    d = json.loads(json.dumps(j))
    edit(d)
    p = tmp_path / "cg.json"
    p.write_text(json.dumps(d))
    with pytest.raises(CgResultError) as e:
        load_cg_result(p)
    assert str(p) in str(e.value) and field in str(e.value)
    assert isinstance(e.value, StaticsError)        # rig-identify's user errors: one line, exit status 2


def test_load_cg_result_unreadable(tmp_path):
    with pytest.raises(CgResultError, match="cannot read"):
        load_cg_result(tmp_path / "none.json")
    p = tmp_path / "cg.json"
    p.write_text("center_of_gravity: [0, 0, 0]\n")
    with pytest.raises(CgResultError, match=r"not JSON .*line 1"):
        load_cg_result(p)
    p.write_text(yaml.safe_dump([1, 2, 3]))
    with pytest.raises(CgResultError, match="not JSON"):
        load_cg_result(p)
    p.write_text("[1, 2, 3]")
    with pytest.raises(CgResultError, match="JSON object"):
        load_cg_result(p)
