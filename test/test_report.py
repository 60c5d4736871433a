"""HTML report of an identification (issue 7): ``rig-identify inertia REC --report DIR``.

The page is rendered in headless Chromium (Debian's ``chromium``, installed by ``make setup``
when run as root): every figure loads; its numbers are checked against the reference
recording's truth.  The folder is written atomically and never replaces a foreign folder.
"""
import html
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from rig_identification import report
from rig_identification.cli import identify_main
from rig_identification.identification import KEYS, identify_inertia

from conftest import recording
from test_identification import RIG, euler_data

CHROMIUM = os.environ.get("RIG_CHROMIUM", "/usr/bin/chromium")


def chromium(args: list[str], profile: Path) -> subprocess.CompletedProcess:
    if not (os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)):
        pytest.fail(f"{CHROMIUM} is missing: the report test renders the page in Debian's chromium "
                    "(`make setup` installs it when run as root; else `sudo apt-get install chromium`)")
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--disable-extensions", f"--user-data-dir={profile}", "--virtual-time-budget=5000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rig_identification.cli", "inertia", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "case16"
    run = cli(recording("visible_case16_clean"), "--json", "--report", out)
    assert run.returncode == 0, run.stderr
    assert f"report: {out / 'index.html'}" in run.stderr
    return out, json.loads(run.stdout)


def test_report_renders_with_all_images(made, tmp_path):
    out, _ = made
    index = out / "index.html"
    page = index.read_text()
    srcs = re.findall(r'<img src="([^"]+)"', page)
    # the ellipses, and per recording the fit and the residuals; relative links to files in the folder
    assert sorted(srcs) == sorted(p.name for p in out.glob("*.png")) and len(srcs) == 3
    dom = chromium(["--dump-dom", index.as_uri()], tmp_path / "profile")
    assert dom.returncode == 0, dom.stderr[-2000:]
    m = re.search(r'<body[^>]*data-images-loaded="(\d+)"[^>]*data-images-total="(\d+)"', dom.stdout)
    assert m, "the page's load check did not run: " + dom.stdout[:500]
    loaded, total = map(int, m.groups())
    assert total == len(srcs) and loaded == total, (loaded, total)
    # and it draws something: a screenshot that is not a blank page
    shot = tmp_path / "shot.png"
    run = chromium([f"--screenshot={shot}", "--window-size=1200,2400", "--hide-scrollbars", index.as_uri()],
                   tmp_path / "profile")
    assert run.returncode == 0 and shot.is_file(), run.stderr[-2000:]
    import matplotlib.image
    img = matplotlib.image.imread(shot)
    assert img.shape[:2] == (2400, 1200)
    assert (img[..., :3] < 0.5).mean() > 0.01  # text, tables and plot lines on a white page


def test_report_numbers(made):
    out, result = made
    data = json.loads((out / "report.json").read_text())
    truth = {"ixx": 2894.0, "ixy": 0.0, "ixz": 0.0, "iyy": 695.0, "iyz": -102.0, "izz": 3101.0}
    assert data["result"]["inertia_about_cg"] == result["inertia_about_cg"]
    for k in KEYS:
        assert abs(result["inertia_about_cg"][k] - truth[k]) < 0.01 * 3101.0, k
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


def test_report_folder_is_atomic(tmp_path, monkeypatch):
    t, w, M = euler_data(noise=0.002, T=30.0, fs=100.0)
    res = identify_inertia(RIG, t, w, M, band_hz=(0.5, 5.0))
    out = tmp_path / "rep"
    report.write_report(out, res, [], modes=False)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {"index.html", "report.json", "ellipses.png", "fit_1.png", "residuals_1.png"} <= set(before)

    def boom(*a, **k):
        raise RuntimeError("disk full")
    monkeypatch.setattr(report, "_residual_figure", boom)
    with pytest.raises(RuntimeError):
        report.write_report(out, res, [], modes=False)
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
    assert code == 2 and "--report needs --model pem" in err, err
    assert not (tmp_path / "new").exists()
    # several recordings: --model thesis is refused too (the joint fit is the prediction-error model's)
    code, err = run(rec, rec, "--model", "thesis")
    assert code == 2 and "one recording at a time" in err, err
