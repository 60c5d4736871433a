"""rig-identify's outputs do not trap (issue "a lab can run a whole rig day with it"): the verdict
first, the conventions said every time, undetermined entries as "not determined", URDF and YAML
exports that carry the JSON's numbers, one entry order for every option, progress on stderr
(silenced by --quiet), a quick --help, --version.

The fits are the rig model's on the clean reference recording's first 40 s (about 10 s each)."""
import contextlib
import dataclasses
import io
import json
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from importlib.metadata import version
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from conftest import background, gather, recording, run_cli

from rig_identification.cli.main import TENSOR, build_parser, identify_main
from rig_identification.cli.recordings import output_axes
from rig_identification.cli.text import origin_line, principal_lines, tensor_table
from rig_identification.estimation.directions import describe_direction
from rig_identification.io import export
from rig_identification.io.rig import load_rig
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import from_tensor, to_tensor

CLEAN = str(recording("visible_case16_clean"))
ORDER = ["ixx", "iyy", "izz", "ixy", "ixz", "iyz"]


run = run_cli


def with_vehicle(folder: Path, **extra) -> Path:
    """The clean recording in ``folder`` (its bag linked) with rig.yaml's body.vehicle: front +y, top +z
    (the Jeep's smallest moment is about body y), and ``extra`` top-level fields."""
    folder.mkdir()
    (folder / "bag").symlink_to(recording("visible_case16_clean") / "bag")
    d = yaml.safe_load((recording("visible_case16_clean") / "rig.yaml").read_text())
    d["body"]["vehicle"] = {"front": "+y", "top": "+z"}
    (folder / "rig.yaml").write_text(yaml.safe_dump(d | extra))
    return folder


def _text():
    """Job: ``rig-identify inertia CLEAN --urdf --end 40``: (exit status, stdout, stderr)."""
    return run("inertia", CLEAN, "--urdf", "--end", "40")


def _vehicle_json():
    """Job: ``rig-identify inertia REC --json --urdf --yaml F --quiet --end 40`` on the clean recording
    with rig.yaml's body.vehicle (front +y, top +z) and ``output_axes: sae`` (no --axes): (exit
    status, the JSON, stderr, the YAML's text, whether a temporary file was left beside it)."""
    tmp = Path(tempfile.mkdtemp(prefix="test_cli_output_"))
    try:
        rec = with_vehicle(tmp / "rec", output_axes="sae")
        path = tmp / "mass_properties.yaml"
        code, out, err = run("inertia", rec, "--json", "--urdf", "--yaml", path, "--quiet", "--end", "40")
        return (code, json.loads(out) if code == 0 else None, err, path.read_text() if path.is_file() else None,
                bool(list(tmp.glob(".*.tmp"))))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


background("cli_output", __file__, _text, {"text": ()})
background("cli_output_json", __file__, _vehicle_json, {"json": ()})


@pytest.fixture(scope="module")
def text_run():
    code, out, err = gather("cli_output")["text"]
    assert code == 0, err
    return out, err


@pytest.fixture(scope="module")
def json_run():
    code, d, err, text, left = gather("cli_output_json")["json"]
    assert code == 0, err
    return d, text, err, left


def test_text_says_the_verdict_first_and_the_conventions(text_run):
    out, _ = text_run
    lines = out.splitlines()
    assert lines[0].startswith("verdict: ok"), lines[0]
    assert "frame: the body frame of rig.yaml (right-handed, as REP-103); origin" in out   # no vehicle: no front
    assert "x forward" not in out and "roll" not in out
    assert "SI units (kg, m, kg·m²)" in out
    assert "about the CG" in out and "the NEGATED products: ixy = −Ixy" in out
    assert "span: 5.0–40.0 s from the first IMU sample" in out
    # one convention in the main table, named in its caption: moments, then products with the
    # vehicle-dynamics sign (truth iyz −102: Iyz ≈ +102); the tensor's entries beside it
    caption = next(i for i, ln in enumerate(lines) if ln.startswith("moments and products of inertia about the CG"))
    rows = [ln.split() for ln in lines[caption + 2:caption + 8]]
    assert [r[0] for r in rows] == ["I" + k[1:] for k in ORDER]
    assert 101 < float(rows[5][1]) < 103 and float(rows[5][5]) == pytest.approx(102.0)
    entries = next(ln for ln in lines if ln.startswith("the inertia tensor's off-diagonal entries about the CG"))
    assert float(entries.split("iyz ")[1].split()[0]) == pytest.approx(-float(rows[5][1]), abs=0.011)
    assert "principal moments (kg·m², ascending)" in out and out.count("  I") >= 3
    assert "about the body-frame origin (parallel-axis theorem" in out
    assert "nan" not in out.lower().replace("nanoseconds", "")


def test_progress_on_stderr_and_quiet_silences_it(text_run, json_run):
    _, err = text_run
    steps = [ln for ln in err.splitlines() if ln.startswith("rig-identify: ")]
    assert any(ln.startswith("rig-identify: reading ") for ln in steps), err
    # the stage that is made of the steps below it is a heading, not a step of 0.0 s
    assert any(ln.startswith("rig-identify: fitting the rig's model to every sensor (") and ln.endswith("):")
               for ln in steps), err
    assert any(ln.startswith("rig-identify: rig fit: ") and ln.endswith(" s") for ln in steps), err
    assert "rig-identify: " not in json_run[2], json_run[2]


def test_json_blocks_in_the_rig_yamls_axes_and_derived_quantities(json_run):
    """No --axes: rig.yaml's ``output_axes: sae`` (front +y, top +z: SAE x = body y, y = body x,
    z = −body z); the JSON stays in body axes and gains the SAE J670 block, whose derived quantities
    (products with the vehicle-dynamics sign, the tensor about the origin, principal moments and axes)
    are those of its own tensor."""
    d, _, _, _ = json_run
    assert d["schema"] == "rig_identification.rig_model_result"
    assert set(d["inertia_about_cg"]) == set(KEYS) == set(d["inertia_std"]) == set(d["inertia_crb"])
    assert d["inertia_about_cg"]["iyz"] < 0      # the tensor's entry: the negated product (truth iyz −102)
    assert d["window"]["start_s"] == pytest.approx(5.0, abs=0.05)
    assert d["window"]["start_s"] + d["window"]["duration_s"] == pytest.approx(40.0, abs=0.01)
    sae = d["sae_j670"]
    assert sae["axes"].startswith("SAE J670 vehicle axes") and "front along +y" in sae["axes"]
    assert sae["inertia_about_cg"]["ixx"] == d["inertia_about_cg"]["iyy"]       # the roll moment
    assert sae["inertia_about_cg"]["iyy"] == d["inertia_about_cg"]["ixx"]
    assert sae["inertia_about_cg"]["izz"] == d["inertia_about_cg"]["izz"]
    assert sae["inertia_about_cg"]["ixy"] == d["inertia_about_cg"]["ixy"]
    assert sae["inertia_about_cg"]["iyz"] == -d["inertia_about_cg"]["ixz"]
    assert sae["products_of_inertia"]["Ixz"] == d["inertia_about_cg"]["iyz"]    # the roll–yaw product
    assert sae["inertia_std"]["ixx"] == d["inertia_std"]["iyy"]
    J = to_tensor([sae["inertia_about_cg"][k] for k in KEYS])
    for k, name in (("ixy", "Ixy"), ("ixz", "Ixz"), ("iyz", "Iyz")):
        assert sae["products_of_inertia"][name] == -sae["inertia_about_cg"][k]
    c = np.array(sae["center_of_gravity"])
    Jo = to_tensor([sae["inertia_about_origin"][k] for k in KEYS])
    np.testing.assert_allclose(Jo, J + d["mass"] * (c @ c * np.eye(3) - np.outer(c, c)), rtol=1e-12)
    V = np.array(sae["principal_axes"]).T
    np.testing.assert_allclose(V.T @ V, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(V @ np.diag(sae["principal_moments"]) @ V.T, J, atol=1e-6 * np.trace(J))


def test_urdf_snippet_parses_and_carries_the_json_numbers(json_run, text_run):
    """The URDF element is the same in the text and the JSON (both in rig.yaml's body axes, whatever
    the output axes) and carries the JSON's mass, CG and tensor entries."""
    d, _, _, _ = json_run
    out, _ = text_run
    snippet = out[out.index("\n<inertial>") + 1:out.index("</inertial>") + len("</inertial>")]
    assert snippet == d["urdf_inertial"]
    el = ET.fromstring(snippet)
    assert float(el.find("mass").get("value")) == pytest.approx(d["mass"])
    xyz = [float(x) for x in el.find("origin").get("xyz").split()]
    assert xyz == pytest.approx(d["center_of_gravity"]["combined"], abs=1e-6)
    inertia = el.find("inertia")
    for k in KEYS:   # URDF's ixy … are the tensor's entries, as geometry_msgs/Inertia and the JSON
        assert float(inertia.get(k)) == pytest.approx(d["inertia_about_cg"][k], rel=1e-5, abs=1e-4), k


def test_yaml_export_round_trips(json_run):
    d, text, _, left = json_run
    y = yaml.safe_load(text)
    assert y["schema"] == export.EXPORT_SCHEMA and y["schema_version"] == 1
    assert y["axes"] == "sae" and y["verdict"] == "ok" and len(y["sources"]) == 1
    assert y["sources"][0].endswith("/rec")          # the clean recording, with body.vehicle (with_vehicle)
    assert y["frame"].startswith("SAE J670 vehicle axes") and "front along +y" in y["frame"]
    sae = d["sae_j670"]
    for k in ORDER:
        assert y["inertia_about_cg"][k] == sae["inertia_about_cg"][k]
        assert y["inertia_std"][k] == sae["inertia_std"][k]
    assert list(y["inertia_about_cg"]) == ORDER
    assert y["products_of_inertia_about_cg"] == sae["products_of_inertia"]
    assert y["principal"]["moments"] == sae["principal_moments"]
    assert y["window_s"]["start"] == d["window"]["start_s"]
    assert not left   # written atomically: no temporary left


def test_rig_output_axes_is_the_default_of_axes(tmp_path):
    """rig.yaml ``output_axes: sae`` (with ``body.vehicle``: front +y, top +z) chooses the axes
    without --axes; --axes body still chooses the body axes and --axes iso8855 the ISO ones, each
    made with the vehicle's orientation; in them the rows are named by the vehicle (body Iyy, SAE
    Ixx the roll moment) and the numbers are the body tensor's turned."""
    rec = SimpleNamespace(rig=load_rig(with_vehicle(tmp_path / "rec", output_axes="sae") / "rig.yaml"))
    assert output_axes(None, [rec])[0].name == "sae"
    body, iso = output_axes("body", [rec])[0], output_axes("iso8855", [rec])[0]
    assert body.name == "body" and iso.name == "iso8855"
    J = to_tensor([2894.0, 0.3, -0.2, 695.0, -102.0, 3101.0])
    std = np.ones(6)
    names = ["I" + k[1:] for k in KEYS]

    def rows(axes):
        table = tensor_table(export.express(1810.0, np.zeros(3), J, std, (), axes))
        return {ln.split()[0]: ln for ln in table if ln.split() and ln.split()[0] in names}
    sae, bod, isr = rows(output_axes(None, [rec])[0]), rows(body), rows(iso)
    value = lambda r: float(r.split()[1])  # noqa: E731
    assert value(sae["Ixx"]) == value(bod["Iyy"]) and value(sae["Iyy"]) == value(bod["Ixx"])
    assert value(sae["Ixz"]) == pytest.approx(-value(bod["Iyz"])) and value(sae["Ixy"]) == value(bod["Ixy"])
    assert sae["Ixx"].endswith("roll moment") and bod["Iyy"].endswith("roll moment")
    assert bod["Ixx"].endswith("pitch moment") and bod["Iyz"].endswith("roll–yaw product")
    assert value(isr["Ixz"]) == pytest.approx(value(bod["Iyz"]))      # z up: the product keeps its sign


def test_undetermined_entries_are_not_determined_everywhere():
    """Entries the recording does not determine: "not determined" in the text's table and the
    tensor's entries, no principal moments, none about the origin, null in the JSON's blocks,
    no URDF element; never nan."""
    J = to_tensor([3000.0, 1.0, -20.0, 800.0, -100.0, 3100.0])
    ex = export.express(1810.0, np.array([0.1, 0.0, -0.2]), J, np.array([3.0, 0.5, 4.0, 120.0, 0.7, 6.0]),
                        ("iyy", "ixy", "iyz"))
    table = tensor_table(ex)
    rows = {ln.split()[0]: ln for ln in table if ln.split() and ln.split()[0] in ("Iyy", "Ixy", "Iyz", "Ixx")}
    for k in ("Iyy", "Ixy", "Iyz"):
        assert "not determined" in rows[k] and not any(ch.isdigit() for ch in rows[k].replace(k, "")), rows[k]
    assert "not determined" not in rows["Ixx"]
    text = "\n".join(table + principal_lines(ex) + [origin_line(ex)])
    assert "principal moments and axes: not determined" in text and "Iyy not determined" in text
    assert "nan" not in text.lower()
    block = export.axes_block(ex)
    assert block["inertia_about_cg"]["iyy"] is None and block["inertia_std"]["ixy"] is None
    assert block["products_of_inertia"]["Iyz"] is None and block["inertia_about_origin"]["iyy"] is None
    assert block["principal_moments"] is None and block["principal_axes"] is None
    json.dumps(block, allow_nan=False)   # never NaN
    assert export.urdf_inertial(ex).startswith("<!-- no URDF <inertial>")


def test_every_tensor_option_takes_the_same_order():
    for argv, dest in ((["modes", "R"], "inertia"),
                       (["plan", "R", "--inertia", *"123456"], "inertia")):
        sub = build_parser(argv)._subparsers._group_actions[0].choices[argv[0]]
        action = next(a for a in sub._actions if a.dest == dest)
        assert tuple(action.metavar) == TENSOR == tuple(ORDER), (argv[0], action.metavar)
        assert "ixx iyy izz ixy ixz iyz" in action.help
    J = export.tensor_from_option([1, 2, 3, 4, 5, 6])
    assert (J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]) == (1, 2, 3, 4, 5, 6)
    np.testing.assert_array_equal(export.entries_from_option([1, 2, 3, 4, 5, 6]), from_tensor(J))


def test_direction_words_are_one_scale():
    # only the weakest is "the most weakly determined"
    D = to_tensor([0, 0, 0, 0, 0, 1.0])
    words = [describe_direction(r, D, scale=2000.0)["level"] for r in (5e-4, 5e-3, 5e-2, 0.2)]
    assert words == ["well determined", "fairly well determined", "weakly determined", "not determined"]
    first, second = describe_direction(5e-3, D, 2000.0, weakest=True), describe_direction(5e-3, D, 2000.0)
    assert first["text"].startswith("The most weakly determined combination is moment Izz: fairly well")
    assert "most weakly" not in second["text"] and second["text"].startswith("Moment Izz is fairly well")
    assert describe_direction(5e-3, D, undetermined=("izz",))["level"] == "not determined"


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as e:
        identify_main(["--version"])
    assert e.value.code == 0 and version("rig_identification") in capsys.readouterr().out
    # --help loads none of the heavy dependencies (and so is quick); no RST markup in it
    code = ("import sys\nfrom rig_identification.cli.main import identify_main\n"
            "for argv in (['--help'], ['inertia', '--help'], ['diagnose', '--help']):\n"
            "    try:\n        identify_main(argv)\n    except SystemExit:\n        pass\n"
            "print('HEAVY', sorted(m for m in sys.modules if m.split('.')[0] in "
            "('scipy', 'rosbags', 'matplotlib', 'numpy')))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "HEAVY []" in p.stdout, p.stdout.splitlines()[-1]
    assert "``" not in p.stdout and ":func:" not in p.stdout and ":mod:" not in p.stdout
    assert "usage: rig-identify inertia" in p.stdout and "ixx iyy izz ixy ixz iyz" in p.stdout


def test_every_command_line_entry_point_says_its_version():
    """Every console script of setup.py (rig-identify, rig-sim, rig-record, the nodes, the client
    and the demo) answers --version with the installed version, exit 0, without starting ROS."""
    bin_dir = Path(sys.executable).parent
    nodes = ("sensor_driver", "tracker", "preprocessor", "identifier", "mass_properties_client", "recorder",
             "rig_visualizer", "demo")
    for prog in ("rig-identify", "rig-sim", "rig-record") + nodes:
        p = subprocess.run([str(bin_dir / prog), "--version"], capture_output=True, text=True, timeout=60)
        assert p.returncode == 0, (prog, p.stderr)
        assert p.stdout.strip() == f"{prog} (rig_identification) {version('rig_identification')}", p.stdout


def test_core_log_records_become_steps_and_warnings():
    """The core modules' logging (INFO: a step, WARNING: a warning now) is what the command line
    shows; a warning shown as it happened is not repeated with the result's warnings."""
    import logging

    from rig_identification.cli.progress import attached, heading
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        with attached() as printer:
            heading("identifying (tracker, fit)")
            logging.getLogger("rig_identification.pipeline.rig_model").info("tracking the pose ...")
            logging.getLogger("rig_identification.pipeline.rig_model").warning("gap in /rig/imu")
            logging.getLogger("rig_identification.pipeline.rig_model").info("fitting")
            printer.finish()                    # as the commands do before their output
            printer.warn_rest(["gap in /rig/imu", "another"])
        with attached(quiet=True) as printer:
            logging.getLogger("rig_identification.diagnosis.rig_diagnosis").info("selection step 1")
        with attached(quiet=True) as printer:
            heading("a stage")
    lines = err.getvalue().splitlines()
    assert lines.pop(0) == "rig-identify: identifying (tracker, fit):"   # a heading: no duration
    assert lines[0] == "rig-identify: tracking the pose …"          # the step's line, cut by the warning
    assert lines[1] == "warning: gap in /rig/imu"
    assert lines[2].startswith("rig-identify: tracking the pose … ") and lines[2].endswith(" s")   # closed
    assert lines[3].startswith("rig-identify: fitting … ") and lines[3].endswith(" s")
    assert lines[4:] == ["warning: another"]                      # quiet: no step line


def test_rig_sim_help_is_quick_and_the_simulation_says_what_it_does(tmp_path, capsys):
    """rig-sim --help (and a usage error) answer without importing the simulator; a run prints
    its steps on stderr (-q: none) and the closing line on stdout."""
    code = ("import sys\nfrom rig_identification.cli.main import sim_main\n"
            "for argv in (['--help'], ['a.yaml', 'out', '--dummy-mass', '3']):\n"
            "    try:\n        sim_main(argv)\n    except SystemExit as e:\n        print('EXIT', e.code)\n"
            "print('HEAVY', sorted(m for m in sys.modules if m.split('.')[0] in ('scipy', 'rosbags', 'numba')))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "usage: rig-sim" in p.stdout and "EXIT 0" in p.stdout and "EXIT 2" in p.stdout, p.stdout
    assert "HEAVY []" in p.stdout, p.stdout.splitlines()[-1]
    assert "--dummy-mass and --dummy-position go together" in p.stderr
    from pathlib import Path

    from rig_identification.cli.sim import sim_main
    config = Path(__file__).resolve().parents[1] / "config" / "rigs" / "default.yaml"
    assert sim_main([str(config), str(tmp_path / "a"), "--duration", "1"]) == 0
    out, err = capsys.readouterr()
    steps = [ln.split(" … ")[0] for ln in err.splitlines()]
    assert steps == ["rig-sim: simulating default (dynamic, 1 s)", f"rig-sim: writing {tmp_path / 'a'}"], err
    assert all(ln.endswith(" s") for ln in err.splitlines()) and out.startswith("rig-sim: wrote ")
    assert sim_main([str(config), str(tmp_path / "b"), "--duration", "1", "-q"]) == 0
    assert capsys.readouterr().err == ""


@pytest.fixture(scope="module")
def rig_fit():
    """The rig model fitted to the clean recording's first 40 s, undiagnosed: (recording, result)."""
    from rig_identification.io.recording import read_recording
    from rig_identification.pipeline.rig_model import fit_whole_recording
    rec = read_recording(recording("visible_case16_clean"))
    return rec, fit_whole_recording(rec, end=40.0, diagnose=False)


def test_quiet_rig_model_output_is_the_short_result_with_the_same_table(rig_fit, capsys):
    """``rig-identify inertia -q`` (the rig model, print_rig_model's ``brief``): the verdict first,
    the same table as the full output, the mass and CG, at most 20 lines, the last saying what the
    full output adds; the full output holds every line of the short one but the last."""
    from rig_identification.cli.rig_model import BRIEF_TAIL, print_rig_model
    _, res = rig_fit
    print_rig_model(res, brief=True)
    short = capsys.readouterr().out.splitlines()
    print_rig_model(res)
    full = capsys.readouterr().out.splitlines()
    assert short[0].startswith("verdict: ") and short[0] == full[0]
    assert any(line.startswith("frame: the body frame of rig.yaml") for line in short)    # the conventions
    assert any("the NEGATED products: ixy = −Ixy" in line for line in short)
    assert short[-1] == BRIEF_TAIL and len(short) <= 20 < len(full)
    assert all(line in full for line in short[:-1])
    rows = [line for line in short if line.split()[:1] in (["Ixx"], ["Iyy"], ["Izz"], ["Ixy"], ["Ixz"], ["Iyz"])]
    assert len(rows) == 6 and any(line.startswith("mass ") for line in short)


def test_the_rig_models_console_and_report_main_tables_use_one_convention(rig_fit, capsys, tmp_path):
    """``rig-identify inertia`` (the rig model) and its ``--report``: both main tables give the
    moments and products of inertia (products with the vehicle-dynamics sign, Ixy = ∫xy dm = −ixy),
    the convention named in each caption, the same numbers row by row (truth iyz −102: Iyz ≈ +102);
    the console's line below its table gives the tensor's entries (−products) with σ and σ/CRB."""
    from rig_identification.cli.rig_model import print_rig_model
    from rig_identification.io.export import PRODUCTS_SIGN
    from rig_identification.report.rig_page import write_rig_report
    rec, res = rig_fit
    print_rig_model(res)
    lines = capsys.readouterr().out.splitlines()
    caption = next(i for i, ln in enumerate(lines) if ln.startswith("moments and products of inertia about the CG"))
    assert f"({PRODUCTS_SIGN})" in lines[caption]
    console = {r[0]: float(r[1]) for r in (ln.split() for ln in lines[caption + 2:caption + 8])}
    assert list(console) == ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"] and 101 < console["Iyz"] < 103
    entries = lines[caption + 8]
    assert entries.startswith("the inertia tensor's off-diagonal entries about the CG (= −products")
    for k in ("ixy", "ixz", "iyz"):
        value, ratio = re.search(rf"{k} ([-+.\d]+) ± [-+.e\d]+ \(σ/CRB ([.\d]+)\)", entries).groups()
        i = KEYS.index(k)
        assert float(value) == pytest.approx(-console["I" + k[1:]], abs=0.011)
        assert float(ratio) == pytest.approx(res.fit.inertia_std[i] / res.fit.crb[i], abs=0.006)
    page = (write_rig_report(tmp_path / "report", res, rec)).read_text()
    table = page.split('id="tensor-table">')[1].split("</table>")[0]
    assert f"<caption>moments and products of inertia, kg·m² ({PRODUCTS_SIGN})</caption>" in table
    rows = [re.findall(r"<t[dh][^>]*>([^<]*)</t[dh]>", r) for r in table.split("<tbody>")[1].split("</tr>")[:-1]]
    report = {r[0].split()[0]: float(r[1]) for r in rows}
    assert report == console, (report, console)
    # σ 100x wider: not_identifiable, every entry withheld in the console's table as in the report's
    wide = dataclasses.replace(res, fit=dataclasses.replace(res.fit, covariance=res.fit.covariance * 1e4))
    assert wide.verdict == "not_identifiable" and wide.withheld == KEYS
    print_rig_model(wide)
    lines = capsys.readouterr().out.splitlines()
    caption = next(i for i, ln in enumerate(lines) if ln.startswith("moments and products of inertia about the CG"))
    for ln in lines[caption + 2:caption + 8]:
        assert ln.split()[1:3] == ["not", "determined"], ln
