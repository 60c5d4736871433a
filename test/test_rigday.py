"""The rig day's hand-over, end to end through the command line (docs/tutorial.md, steps 4 and 6):
``rig-identify cg BASELINE DUMMY --json > cg.json``, then ``rig-identify inertia RUN --cg cg.json
--report DIR``.  The fit, the text and the report all use the static test's CG and say so: the
report's header names cg.json and its σ instead of "rig.yaml body.center_of_gravity".

The shake is the clean reference recording (its first 45 s), the static pair the reference pair
(its CG 2.2 mm below truth.yaml's, the body origin)."""
import html
import json
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import background, gather, recording, run_cli
from report_render import render

CLEAN = recording("visible_case16_clean")
BASE = recording("visible_case16_static/static_baseline")
DUMMY = recording("visible_case16_static/static_dummy")


run = run_cli


@pytest.fixture(scope="module")
def cg_json():
    """``rig-identify cg BASELINE DUMMY --json``'s result."""
    code, out, err = run("cg", BASE, DUMMY, "--json", "-q")
    assert code == 0, err
    return json.loads(out)


def test_cg_json_gives_each_state_window_as_start_and_end_take_it(cg_json):
    """cg.json's state windows in s from each recording's first IMU sample (the header stamps
    beside): what --start/--end would take to average the same stretch again."""
    from rig_identification.io.recording import read_recording
    cg = cg_json
    assert [s["label"] for s in cg["states"]] == ["baseline", "dummy"]
    for s, path in zip(cg["states"], (BASE, DUMMY)):
        t0 = float(read_recording(path).sensors.t_start)
        np.testing.assert_allclose(s["window_s"], np.array(s["window"]) - t0, rtol=0, atol=1e-9)
        assert 0.0 <= s["window_s"][0] < s["window_s"][1] <= 10.0 + 1e-6
    assert cg["units"]["states.window_s"].startswith("s from the first IMU sample")


def test_cg_plan_says_what_it_is_doing_on_stderr():
    """Progress lines for cg-plan (its search takes ~10 s), silenced by -q.  (cg itself reads and
    fits in ~0.3 s after its imports: no progress lines.)"""
    code, out, err = run("cg-plan", BASE, "--cg-guess", "0", "0", "0", "--masses", "50", "--position", "0.5", "0.5",
                         "0.3")
    assert code == 0, err
    steps = [ln.split(" … ")[0] for ln in err.splitlines() if ln.startswith("rig-identify: ")]
    assert steps == [f"rig-identify: reading {BASE} (its sensor noise)",
                     "rig-identify: predicting the CG σ of the planned test",
                     "rig-identify: searching dummy masses (50 kg) and positions for ±2 mm"], err
    assert out.startswith("rig: ")
    assert "rig-identify: " not in run("cg-plan", BASE, "--masses", "50", "--position", "0.5", "0.5", "0.3", "-q")[2]


def _chain():
    """Job: ``cg`` on the static pair, then ``inertia --cg cg.json`` (the default: the rig model)
    on 45 s of the clean run with ``--report``, ``--yaml`` and ``--urdf`` (in the worker's
    process).  Returns (cg JSON, the rig model's JSON, its exit status and stderr, the report's
    index.html, its report.json, the YAML export)."""
    code, out, err = run_cli("cg", BASE, DUMMY, "--json", "-q")
    assert code == 0, err
    with tempfile.TemporaryDirectory() as tmp:
        cg_file = Path(tmp) / "cg.json"
        cg_file.write_text(out)
        report, exported = Path(tmp) / "report", Path(tmp) / "mass.yaml"
        code2, out2, err2 = run_cli("inertia", CLEAN, "--cg", cg_file, "--end", "45", "--json", "-q", "--report",
                                    report, "--yaml", exported, "--urdf")
        pngs = sorted(p.name for p in report.glob("*.png"))
        seen = render(report, Path(tmp) / "render") if code2 == 0 else None
        return (out, out2, code2, err2, (report / "index.html").read_text(), (report / "report.json").read_text(),
                exported.read_text(), pngs, seen)


background("rig_day_chain", __file__, _chain, {"run": ()}, first=True)


def test_the_rig_model_carries_the_static_cg_and_finds_its_own():
    """The chain static pair → ``cg`` → ``inertia --cg cg.json`` (45 s of the clean run): the static
    CG is the prior and is shown as such (the JSON and the report name cg.json); the run alone places the CG within
    1 mm and 3 σ of the truth (the body origin) with σ at least ten times smaller in height than
    the static test's; the combined CG is the tensor's point, and the tensor is within 1 % of the
    truth (its σ: the next test)."""
    cg_text, out, code, err, page = gather("rig_day_chain")["run"][:5]
    assert code == 0, err
    cg = json.loads(cg_text)
    res = json.loads(out)
    c = res["center_of_gravity"]
    assert c["static_source"].endswith("cg.json")
    static_row = html.unescape(page).split("<td>static</td>")[1].split("</tr>")[0]
    assert static_row.endswith(f"<td>{c['static_source']}</td>"), static_row
    np.testing.assert_allclose(c["static"], cg["center_of_gravity"])
    np.testing.assert_allclose(c["static_std"], cg["center_of_gravity_std"])
    dyn, dyn_std = np.array(c["dynamic"]), np.array(c["dynamic_std"])
    assert np.all(np.abs(dyn) < 1e-3) and np.all(np.abs(dyn) < 3 * dyn_std), (dyn, dyn_std)
    assert dyn_std[2] < 0.1 * cg["center_of_gravity_std"][2]
    assert c["agree"] and res["verdict"] == "ok", res["verdict"]
    for k, t in res["truth_comparison"].items():
        assert abs(t["error_percent"]) < 1.0, (k, t)


def test_the_rig_models_sigma_after_the_chain_covers_its_error():
    """The chain's tensor (the test above) within 3 σ of the truth, its σ carrying the CG's."""
    _, out, code, err = gather("rig_day_chain")["run"][:4]
    assert code == 0, err
    for k, t in json.loads(out)["truth_comparison"].items():
        assert abs(t["error_sigma"]) < 3.0, (k, t)


def test_the_default_inertia_is_the_rig_model_with_its_report_yaml_and_urdf():
    """``inertia`` fits the rig model; its report shows the tensor with σ and the
    Cramér–Rao bound, the CG three ways, every channel against its noise and a figure per sensor
    group; report.json's products are the negated entries; the YAML export and the URDF element
    carry the same numbers (the fitted CG and mass)."""
    _, out, code, err, page, data, exported, pngs, _ = gather("rig_day_chain")["run"]
    assert code == 0, err
    res = json.loads(out)
    assert res["schema"] == "rig_identification.rig_model_result" and res["verdict"] == "ok"
    for words in ("Cramér–Rao bound", "the swinging body alone", "Every channel against its noise", "tension:c0",
                  "Restarts: other minima"):
        assert words in page, words
    assert pngs == ["fit_accelerometer.png", "fit_exciter_force.png", "fit_gyro.png", "fit_inclinometer.png",
                    "fit_tensions.png", "principal_axes.png"]
    rep = json.loads(data)
    assert rep["result"]["inertia_about_cg"] == res["inertia_about_cg"]
    mp = rep["mass_properties"]
    for k, v in res["inertia_about_cg"].items():
        sign = -1.0 if k in ("ixy", "ixz", "iyz") else 1.0
        assert mp["about_cg"]["I" + k[1:]] == pytest.approx(sign * v, abs=1e-9)
        assert mp["crb_std"]["I" + k[1:]] == pytest.approx(res["inertia_crb"][k], rel=1e-9)
    y = yaml.safe_load(exported)
    assert y["verdict"] == "ok" and y["inertia_about_cg"]["iyy"] == pytest.approx(res["inertia_about_cg"]["iyy"])
    np.testing.assert_allclose(y["center_of_gravity"], res["center_of_gravity"]["combined"], atol=1e-12)
    assert y["mass"] == pytest.approx(res["mass"]) and y["center_of_gravity_source"].startswith("fitted")
    u = ET.fromstring(res["urdf_inertial"])
    assert float(u.find("mass").get("value")) == pytest.approx(res["mass"], rel=1e-6)
    assert float(u.find("inertia").get("iyz")) == pytest.approx(res["inertia_about_cg"]["iyz"], rel=1e-6)


def test_the_rig_models_report_reads_in_a_browser():
    """The default report of the chain (the rig model), rendered in headless Chromium: every
    figure loaded and inside the page's width, every table inside 800 px (A4), no nan/inf in its
    text, the verdict before the tensor table, the job's sections in order; the screenshot is not
    blank (test_report.render)."""
    *_, pngs, seen = gather("rig_day_chain")["run"]
    assert seen is not None
    assert seen["images"] == len(pngs) == seen["loaded"], seen["images"]
    assert seen["wide"] == [] and seen["bad_words"] == [], (seen["wide"], seen["bad_words"])
    # at the headless window's 800 px (an A4 page's width) every table fits: the print style sheet
    assert seen["wide_tables"] == [], seen["wide_tables"]
    assert seen["verdict"].startswith("ok") and seen["verdict_before_tensor"], seen["verdict"]
    text = seen["text"]
    heads = ["Mass and centre of gravity", "Moments and products of inertia about the CG", "Principal moments and axes",
             "What the model leaves out", "Every channel against its noise", "Cables and load cells",
             "Measured vs the model: tensions"]
    assert [text.index(h) for h in heads] == sorted(text.index(h) for h in heads), heads
