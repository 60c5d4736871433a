"""HTML report of an identification (issue 7, and "a report an engineer signs"):
``rig-identify inertia REC --report DIR``.

The pages are rendered in headless Chromium (Debian's ``chromium``, installed by ``make setup``
when run as root) and checked there, on what a reader sees: every figure loads, no ``nan`` or
``inf`` anywhere in the text, the validation verdict comes before the tensor, an entry the
recording does not determine reads "not determined", a model error reads "not trustworthy" and
sends the reader to ``rig-identify diagnose``.  One page comes from a
real identification of a reference recording (its numbers checked against the truth); the
others from one small in-memory fit dressed with each verdict (no simulation).  The folder is
written atomically and never replaces a foreign folder.
"""
import copy
import html
import json
import re
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import background, gather, recording, run_cli
from report_render import render
from synthetic import RIG, euler_data

from rig_identification.cli.main import identify_main
from rig_identification.estimation.identification import identify_inertia
from rig_identification.estimation.inertia_result import InertiaResult
from rig_identification.io.export import AxesError
from rig_identification.io.verdict import KEYS, Check, Validation
from rig_identification.report import page as report
from rig_identification.report.verdict import headline

SYMBOL = {"ixx": "Ixx", "iyy": "Iyy", "izz": "Izz", "ixy": "Ixy", "ixz": "Ixz", "iyz": "Iyz"}


def assert_readable(out: Path, seen: dict, result: InertiaResult | None = None) -> None:
    """What every page must be: every figure loaded, no nan/inf text, the verdict first, a
    report.json without NaN holding the numbers of the page's tensor table."""
    srcs = re.findall(r'<img src="([^"]+)"', (out / "index.html").read_text())
    assert sorted(srcs) == sorted(p.name for p in out.glob("*.png"))
    assert seen["images"] == len(srcs) and seen["loaded"] == seen["images"], seen
    assert seen["bad_words"] == [], seen["bad_words"]
    assert seen["verdict_before_tensor"], seen["ids"]
    assert "figures loaded" not in seen["text"] and "loading" not in seen["text"]

    def refuse(x):
        raise ValueError(f"report.json holds {x}")
    data = json.loads((out / "report.json").read_text(), parse_constant=refuse)
    mp = data["mass_properties"]
    for row in seen["tensor"]:
        sym = row[0].split()[0]
        value = mp["about_cg"][sym]
        assert row[1] == ("not determined" if value is None else f"{value:.2f}"), (row, value)
    if result is not None and result.validation is not None:
        assert headline(result.validation) in seen["verdict"]
        # the precision against the lab's target, in the verdict box
        assert result.precision.text() in seen["verdict"]


def _made():
    """Job: `rig-identify inertia visible_case16_clean --model pem --json --report OUT` (in the worker's
    process), OUT in a fresh temporary folder that the module's tests read and the fixture
    removes.  Returns (OUT, exit status, stdout, stderr)."""
    out = Path(tempfile.mkdtemp(prefix="test_report_")) / "case16"
    code, stdout, stderr = run_cli("inertia", recording("visible_case16_clean"), "--model", "pem", "--json",
                                   "--report", out)
    return out, code, stdout, stderr


background("report", __file__, _made, {"case16": ()})


@pytest.fixture(scope="module")
def made():
    out, code, stdout, stderr = gather("report")["case16"]
    assert code == 0, stderr
    assert f"report: {out / 'index.html'}" in stderr
    yield out, json.loads(stdout)
    shutil.rmtree(out.parent, ignore_errors=True)


@pytest.fixture(scope="module")
def fitted():
    """One small fit of Euler's equations (30 s, 100 Hz): the in-memory pages' base."""
    t, w, M = euler_data(noise=0.002, T=30.0, fs=100.0)
    return identify_inertia(RIG, t, w, M, band_hz=(0.5, 5.0))


def not_identifiable(res: InertiaResult) -> InertiaResult:
    """The fit with verdict not_identifiable: Ixx and the products with x undetermined (their σ
    not finite, as a failed fit leaves them)."""
    std = res.inertia_std.copy()
    std[[0, 1, 2]] = [np.nan, np.inf, np.nan]
    return replace(copy.deepcopy(res), inertia_std=std, validation=Validation("not_identifiable", (
        Check("whiteness", 4.1, 44.0, True, "largest residual line 4.1× its local median level"),
        Check("segments", None, None, None, "does not apply"),
        Check("identifiable", 0.42, 0.1, False, "largest relative σ ixx 42 % (limit 10 %)")),
        undetermined=("ixx", "ixy", "ixz"),
        advice=("the body hardly turned about x: move the exciter farther from that axis",)))


def model_error(res: InertiaResult) -> InertiaResult:
    """The fit with verdict model_error, σ the residuals' (no propagated-noise σ)."""
    return replace(copy.deepcopy(res), crb_std=None, validation=Validation("model_error", (
        Check("whiteness", 85.0, 44.0, False, "largest residual line 85.0× its local median level"),
        Check("sub_bands", 25.0, 7.5, False, "izz 2790 below vs 2850 kg·m² above")), failed=("whiteness",
                                                                                          "sub_bands")))


def failed_fit() -> InertiaResult:
    """A fit that could not be made at all (pipeline.unidentified): every number NaN, no series."""
    nan = np.full(6, np.nan)
    r = InertiaResult(RIG.mass, RIG.require_cg().copy(), np.full((3, 3), np.nan), nan, np.full((6, 6), np.nan),
                      0.0, 30.0, 3000, (np.nan, np.nan), np.full(3, np.nan), np.full(3, np.nan),
                      warnings=["the fit's normal equations are singular"])
    return replace(r, validation=Validation("not_identifiable",
                                            (Check("identifiable", None, 0.1, False, "non-finite numbers"),),
                                            undetermined=tuple(KEYS), advice=("splay the ceiling anchors outward",)))


@pytest.fixture(scope="module")
def pages(fitted, tmp_path_factory):
    """The in-memory pages: {name: (folder, result, what Chromium saw)}."""
    base = tmp_path_factory.mktemp("pages")
    out = {}
    for name, res in (("not_identifiable", not_identifiable(fitted)), ("model_error", model_error(fitted)),
                      ("failed", failed_fit())):
        folder = base / name
        report.write_report(folder, res, [], modes=False, rig=RIG)
        out[name] = (folder, res, render(folder, base / "render"))
    return out


def test_report_renders_with_all_images(made, tmp_path):
    out, _ = made
    seen = render(out, tmp_path)
    assert_readable(out, seen)
    # the principal axes, the ellipses, and per recording the fit and the residuals
    assert len(seen["tensor"]) == 6 and seen["images"] == 4
    assert seen["verdict"].startswith("verdict: ok")
    assert [r[0] for r in seen["checks"]][:2] == ["segments", "sub_bands"]
    for word in ("REP-103", "SAE J670", "rig_identification 0.1.0", "visible_case16_clean", "rig.yaml",
                 "Principal moments and axes"):
        assert word in seen["text"], word


def test_report_numbers(made):
    out, result = made
    data = json.loads((out / "report.json").read_text())
    truth = {"ixx": 2894.0, "ixy": 0.0, "ixz": 0.0, "iyy": 695.0, "iyz": -102.0, "izz": 3101.0}
    assert data["result"]["inertia_about_cg"] == result["inertia_about_cg"]
    for k in KEYS:
        assert abs(result["inertia_about_cg"][k] - truth[k]) < 0.01 * 3101.0, k
    # the page's products carry the vehicle-dynamics sign: the negated off-diagonal entries
    mp = data["mass_properties"]
    for k in KEYS:
        sign = -1.0 if k in ("ixy", "ixz", "iyz") else 1.0
        assert mp["about_cg"][SYMBOL[k]] == pytest.approx(sign * result["inertia_about_cg"][k], abs=1e-9)
        assert mp["about_origin"][SYMBOL[k]] == pytest.approx(mp["about_cg"][SYMBOL[k]], abs=1e-6)  # CG at origin
    assert mp["errors_against_truth"]["Iyz"]["truth"] == 102.0
    # principal moments: the tensor's eigenvalues, ascending (their sum is the trace)
    p = mp["principal_moments"]
    assert p == sorted(p) and sum(p) == pytest.approx(mp["about_cg"]["Ixx"] + mp["about_cg"]["Iyy"]
                                                      + mp["about_cg"]["Izz"], rel=1e-9)
    page = (out / "index.html").read_text()
    assert "2894.00" in page and "error / σ" in page        # the truth column of the tensor table
    ident = data["identifiability"]
    assert len(ident) == 6
    rel = [r["relative_std"] for r in ident]
    assert rel == sorted(rel, reverse=True)
    # case 16: the exciter (a horizontal rotating force below a corner) pitches the body hard (about
    # y) and yaws it least: pitch inertia is the best determined, yaw inertia the weakest, said so
    assert ident[0]["mostly"] == "izz" and ident[-1]["mostly"] == "iyy"
    assert "hardly turned about z" in ident[0]["text"], ident[0]["text"]
    for r in ident:
        assert html.escape(r["text"]) in page
    # the σ of the eigen-directions bound the entries' σ: the weakest is at least the largest entry σ
    assert ident[0]["std"] >= max(result["inertia_std"].values()) * 0.999
    # modes: geometry (rig.yaml + identified tensor) vs the recording's free vibration, within 2 %
    (modes,) = data["modes"]
    assert len(modes["modes"]) == 2  # 4 inextensible cables: a 2-DOF mechanism
    for m in modes["modes"]:
        assert m["estimated_hz"] is not None, m
        assert abs(m["difference_percent"]) < 2.0, m
        assert abs(m["geometric_hz"] - m["geometric_true_hz"]) < 1e-3 * m["geometric_true_hz"]
    assert abs(modes["exciter_frequency_hz"] - 1.05) < 1e-3


def test_not_identifiable_entries_read_not_determined(pages):
    out, res, seen = pages["not_identifiable"]
    assert_readable(out, seen, res)
    rows = {r[0].split()[0]: r for r in seen["tensor"]}
    for k in res.validation.undetermined:
        assert rows[SYMBOL[k]][1] == "not determined", rows[SYMBOL[k]]
        assert not re.search(r"\d", " ".join(rows[SYMBOL[k]][1:])), rows[SYMBOL[k]]   # no number in the row
    assert rows["Iyy"][1] == f"{res.inertia[1, 1]:.2f}"
    assert "What to change" in seen["verdict"] and res.validation.advice[0] in seen["verdict"]
    assert "Principal moments and axes: not determined" in seen["text"]
    data = json.loads((out / "report.json").read_text())
    assert data["result"]["inertia_about_cg"]["ixx"] is None and data["mass_properties"]["about_cg"]["Ixx"] is None
    assert data["mass_properties"]["principal_moments"] is None
    # a fit that could not be made at all: a page that says so, every entry not determined
    out, res, seen = pages["failed"]
    assert_readable(out, seen, res)
    assert [r[1] for r in seen["tensor"]] == ["not determined"] * 6
    assert "No fit output" in seen["text"]


def test_model_error_is_said_untrusted_and_sends_to_diagnose(pages):
    out, res, seen = pages["model_error"]
    assert_readable(out, seen, res)
    assert "not trustworthy" in seen["verdict"] and "widened" in seen["verdict"]
    assert "rig-identify diagnose" in seen["verdict"]
    assert [r[4] for r in seen["checks"]] == ["FAIL", "FAIL"]
    # no propagated-noise σ for this fit: its column is left out, not filled with nan
    assert len(seen["tensor"][0]) == 5 and "σ propagated" not in seen["text"]


def test_report_folder_is_atomic(pages, fitted, tmp_path, monkeypatch):
    out = tmp_path / "rep"
    shutil.copytree(pages["model_error"][0], out)       # an earlier report
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {"index.html", "report.json", "ellipses.png", "principal_axes.png", "fit_1.png",
            "residuals_1.png"} <= set(before)

    def boom(*a, **k):
        raise RuntimeError("disk full")
    monkeypatch.setattr(report, "ellipsoid_figure", boom)
    with pytest.raises(RuntimeError):
        report.write_report(out, fitted, [], modes=False)
    # the earlier report is untouched, and no half-written folder is left beside it
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["rep"]


def test_report_refuses_foreign_folder_and_thesis_model(tmp_path, capsys):
    foreign = tmp_path / "notes"
    foreign.mkdir()
    (foreign / "todo.txt").write_text("keep me")
    rec = str(recording("visible_case16_clean"))

    def run(*args):
        code = identify_main(["inertia", *map(str, args)])
        return code, capsys.readouterr().err
    # refused before the recording is even read: no fit is spent on a report that cannot be written
    code, err = run(rec, "--report", foreign)
    assert code == 2 and str(foreign) in err and "refusing to replace" in err, err
    assert (foreign / "todo.txt").read_text() == "keep me"
    code, err = run(rec, "--model", "thesis", "--report", tmp_path / "new")
    assert code == 2 and "--report needs --model rig or pem" in err, err
    assert not (tmp_path / "new").exists()
    # several recordings: --model thesis is refused too (the joint fit is the prediction-error model's)
    code, err = run(rec, rec, "--model", "thesis")
    assert code == 2 and "one recording at a time" in err, err


def test_report_in_sae_axes(fitted, tmp_path):
    """rig.yaml output_axes / --axes sae: the page gives the mass properties in SAE J670 axes
    too (x forward, y right, z down), turned from the body frame by rig.yaml's body.vehicle —
    here front +y, top +z: SAE x = body y, y = body x, z = −body z — and report.json holds
    them; the moments are named by the vehicle (Iyy the roll moment in the body axes)."""
    from dataclasses import replace

    from rig_identification.io.vehicle import Vehicle
    res = replace(copy.deepcopy(fitted), center_of_gravity=np.array([0.1, 0.2, 0.3]))
    out = tmp_path / "sae"
    rig = replace(RIG, vehicle=Vehicle("+y", "+z"))
    report.write_report(out, res, [], modes=False, rig=rig, axes="sae")
    data = json.loads((out / "report.json").read_text())
    sae = data["output_axes"]
    assert sae["axes"] == "sae" and sae["center_of_gravity"] == pytest.approx([0.2, 0.1, -0.3])
    body = data["result"]["inertia_about_cg"]
    for k, (b, sign) in {"ixx": ("iyy", 1), "iyy": ("ixx", 1), "izz": ("izz", 1), "ixy": ("ixy", 1),
                         "ixz": ("iyz", -1), "iyz": ("ixz", -1)}.items():
        assert sae["inertia_about_cg"][k] == pytest.approx(sign * body[b], rel=1e-9, abs=1e-9), k
    # products with the vehicle-dynamics sign: the negated tensor entries in those axes
    assert sae["products_of_inertia"]["Ixy"] == pytest.approx(-sae["inertia_about_cg"]["ixy"], abs=1e-9)
    page = (out / "index.html").read_text()
    assert "In SAE J670 axes" in page and "y right, z down" in page
    assert "Iyy (roll moment)" in page and "Ixx (pitch moment)" in page
    assert data["report"]["vehicle"] == {"front": "+y", "top": "+z"}
    with pytest.raises(AxesError, match="body.vehicle"):     # without it: refused
        report.write_report(tmp_path / "refused", res, [], modes=False, rig=RIG, axes="sae")
    # the body-axes page has no such section
    plain = tmp_path / "body"
    report.write_report(plain, res, [], modes=False, rig=RIG)
    assert "output_axes" not in json.loads((plain / "report.json").read_text())
    text = (plain / "index.html").read_text()
    assert "Ixx (moment about x)" in text and "roll moment" not in text and "x forward" not in text


def test_report_names_the_job_and_the_mass_with_its_sigma(tmp_path, capsys):
    """--vehicle-name, --customer and --operator head the report (HTML escaped) and report.json; the
    mass carries its σ (rig.yaml survey.mass, default the scale's 0.1 %: 1.81 kg of 1810); each
    option without --report, or of two lines, is refused before the fit."""
    rec = str(recording("visible_case16_clean"))
    out = tmp_path / "report"
    code = identify_main(["-q", "inertia", rec, "--quick", "--report", str(out), "--vehicle-name", "Jeep <Wrangler>",
                          "--customer", "ACME & Co", "--operator", "J. Doe"])
    assert code == 0, capsys.readouterr().err
    page = (out / "index.html").read_text()
    assert ("<tr><th>vehicle</th><td>Jeep &lt;Wrangler&gt;</td></tr><tr><th>customer</th><td>ACME &amp; Co</td></tr>"
            "<tr><th>operator</th><td>J. Doe</td></tr>") in page
    head = json.loads((out / "report.json").read_text())["report"]
    assert (head["vehicle_name"], head["customer"], head["operator"]) == ("Jeep <Wrangler>", "ACME & Co", "J. Doe")
    assert head["mass_std"] == pytest.approx(0.001 * 1810.0) and "Mass <b>1810 kg</b> ± 1.81 kg" in page
    capsys.readouterr()
    assert identify_main(["inertia", rec, "--customer", "ACME"]) == 2
    assert "give --report DIR too" in capsys.readouterr().err
    assert identify_main(["inertia", rec, "--report", str(tmp_path / "r2"), "--operator", "J.\nDoe"]) == 2
    assert "--operator: one line" in capsys.readouterr().err and not (tmp_path / "r2").exists()
