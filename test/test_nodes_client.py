"""mass_properties_client's text (``client.format_rig_model``) says what ``rig-identify inertia``
says: the verdict first, the conventions (body frame, SI units, the tensor's off-diagonal entries
are the negated products of inertia), the entries in rig-identify's order with σ, the bound and
their truth, the products with the vehicle-dynamics sign, and "not determined" beside an entry
the recording does not determine.

The answer is a real fit's JSON (``RigModelResult.to_dict``, what ~/identify_rig_model returns):
``rig-identify inertia --cg cg.json`` on the clean reference run (test_rigday's chain job); no DDS."""
import copy
import json

import pytest

pytest.importorskip("rclpy")

import test_rigday  # noqa: E402,F401  (registers the "rig_day_chain" job this module reads)
from conftest import gather, recording  # noqa: E402

from rig_identification.io.recording import read_recording  # noqa: E402
from rig_identification.nodes.client import KEYS, format_rig_model  # noqa: E402


@pytest.fixture(scope="module")
def answer():
    return json.loads(gather("rig_day_chain")["run"][1]), read_recording(recording("visible_case16_clean")).truth


def rows(text: str) -> dict[str, str]:
    """The table's rows of moments and products (Ixx … Iyz) by tensor key (ixx … iyz)."""
    return {line.split()[0].lower(): line for line in text.splitlines()
            if line.split() and line.split()[0].startswith("I") and line.split()[0].lower() in KEYS}


def test_verdict_first_then_the_conventions(answer):
    d, truth = answer
    lines = format_rig_model(d, truth).splitlines()
    assert lines[2] == f"verdict: {d['verdict']}" and d["verdict"] == "ok"
    assert lines[3].startswith("frame: the body frame of rig.yaml") and "SI units" in lines[3]
    assert "the NEGATED products" in lines[4] and "vehicle-dynamics sign" in lines[4]


def test_undetermined_entry_is_marked_not_determined(answer):
    d, truth = answer
    d = copy.deepcopy(d)
    d["undetermined"] = ["ixy"]                      # as in a not_identifiable answer
    d["verdict"] = "not_identifiable"
    text = format_rig_model(d, truth)
    assert "not determined" in rows(text)["ixy"]
    assert "not determined" not in rows(text)["ixx"]
    assert "no entry above is an estimate to use (verdict not_identifiable)" in text


def test_the_top_level_help_describes_every_verb_and_the_cg_procedure():
    from rig_identification.nodes.client import VERBS, parser
    text = parser("identify").format_help()
    for verb in VERBS:
        assert f"\n  {verb} " in text or f"\n  [{verb}] " in text, verb
    steps = [text.index(f"mass_properties_client {v}") for v in ("cg-capture baseline", "cg-capture dummy",
                                                                   "cg-estimate --write-rig")]
    assert steps == sorted(steps)               # in the order of the procedure
    assert all(len(line) <= 100 for line in text.splitlines())
    assert "cg-capture baseline|dummy" in parser("cg-capture").format_help()   # each verb's help has it too


def test_entries_with_the_bound_products_sign_and_the_cg_of_both_tests(answer):
    """Each entry with σ and the bound, products with the vehicle-dynamics sign and their error
    against the truth, the CG of the static test, the run alone and both."""
    res, truth = answer
    text = format_rig_model(res, truth)
    lines = text.splitlines()
    assert lines[2] == f"verdict: {res['verdict']}" and res["verdict"] == "ok"
    r = rows(text)
    assert list(r) == ["ixx", "iyy", "izz", "ixy", "ixz", "iyz"]
    iyz = r["iyz"].split()
    assert float(iyz[1]) == pytest.approx(-res["inertia_about_cg"]["iyz"], abs=0.006)      # the product's sign
    assert float(iyz[3]) == pytest.approx(res["inertia_crb"]["iyz"], rel=2e-3)
    assert float(iyz[4]) == pytest.approx(-truth["inertia_about_cg"]["iyz"], abs=0.006)
    ixx = r["ixx"].split()
    err = 100 * (res["inertia_about_cg"]["ixx"] - truth["inertia_about_cg"]["ixx"]) / truth["inertia_about_cg"]["ixx"]
    assert float(ixx[5].rstrip("%")) == pytest.approx(err, abs=6e-4)
    for label in ("CG static", "CG dynamic", "CG combined"):
        assert any(line.startswith(label) for line in lines), label
    assert "tension:c0" in lines[-1] or any("tension:c0" in line for line in lines)
