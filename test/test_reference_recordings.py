"""Acceptance on the reference recordings (independent simulator, realistic noise), through
``rig-identify inertia --json`` (the rig model, every sensor an output).

visible_case16_clean whole (issue 33): verdict ok; every diagonal entry within 0.5 % of
truth.yaml, every product within 0.5 % of the largest diagonal, each error within 3 σ, and σ
within 2× of the Cramér–Rao bound of the same recording.
"""
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np
from conftest import background, gather, recording, run_cli

from rig_identification.io.recording import read_recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import physically_consistent, to_tensor


def _cli(name: str, report: bool, *args: str):
    """Job: `rig-identify inertia` (``identify_main`` in the worker's process) on the reference
    recording ``name`` with ``args`` (and, with ``report``, ``--report`` into a temporary folder).
    Returns (exit status, stdout, stderr, the report's index.html or None)."""
    tmp = Path(tempfile.mkdtemp(prefix="test_reference_recordings_"))
    try:
        code, stdout, stderr = run_cli("inertia", recording(name), *args,
                                       *(["--report", tmp / "report"] if report else []))
        page = tmp / "report" / "index.html"
        return code, stdout, stderr, page.read_text() if page.is_file() else None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


background("reference_cli", __file__, _cli, {
    "case16": ("visible_case16_clean", False, "--json", "--quiet"),
})


def test_identify_reference_recording():
    rec = read_recording(recording("visible_case16_clean"))
    code, stdout, stderr, _ = gather("reference_cli", "case16")["case16"]
    assert code == 0, stderr
    d = json.loads(stdout)
    assert d["verdict"] == "ok", d["warnings"]
    cmp = d["truth_comparison"]
    for k in KEYS:
        assert abs(cmp[k]["error_percent"]) < 0.5, (k, cmp[k])
        assert abs(cmp[k]["error_sigma"]) < 3.0, (k, cmp[k])
        assert 0.5 < d["sigma_over_crb"][k] < 2.0, (k, d["sigma_over_crb"])
    J = to_tensor(np.array([d["inertia_about_cg"][k] for k in KEYS]))
    assert physically_consistent(J)
    tru = rec.truth
    assert abs(d["mass"] - tru["mass"]) < 3 * d["mass_std"]


def test_cli_user_error_no_traceback(tmp_path):
    code, _, err = run_cli("inertia", tmp_path)
    assert code == 2
    assert "no rig.yaml" in err and "Traceback" not in err
