"""mass_properties_client's table (``client.format_table``) says what ``rig-identify inertia``
says: the verdict first (or that the node's fit has none), the conventions (body frame, SI
units, the tensor's off-diagonal entries are the negated products of inertia), the entries in
rig-identify's order with their truth, the products with the vehicle-dynamics sign, and
"not determined" for a null entry instead of a crash.

The answer is a real fit's JSON (``InertiaResult.to_dict``, what ~/identify_inertia returns)
of the clean reference recording (--quick, a few seconds); no DDS."""
import copy
import json

import pytest

pytest.importorskip("rclpy")

import test_rigday  # noqa: E402,F401  (registers the "rig_day_chain" job this module reads)
from conftest import gather, recording  # noqa: E402

from rig_identification.io.recording import read_recording  # noqa: E402
from rig_identification.nodes.client import KEYS, UNVALIDATED, format_table  # noqa: E402
from rig_identification.pipeline.offline import identify_recording  # noqa: E402


@pytest.fixture(scope="module")
def answer():
    rec = read_recording(recording("visible_case16_clean"))
    d = json.loads(json.dumps(identify_recording(rec).to_dict(t0=float(rec.sensors.t_start))))
    return d, rec.truth


def rows(text: str) -> dict[str, str]:
    """The table's rows of moments and products (Ixx … Iyz) by tensor key (ixx … iyz)."""
    return {line.split()[0].lower(): line for line in text.splitlines()
            if line.split() and line.split()[0].startswith("I") and line.split()[0].lower() in KEYS}


def test_verdict_first_then_the_conventions(answer):
    d, truth = answer
    lines = format_table(d, truth).splitlines()
    assert lines[2] == d["validation"]["summary"] and lines[2].startswith("verdict: ok")
    assert lines[3].startswith("frame: the body frame of rig.yaml") and "SI units" in lines[3]
    assert "the NEGATED products" in lines[4] and "vehicle-dynamics sign" in lines[4]
    # an answer without validation (an identifier older than the client): the table says so
    unvalidated = dict(d, validation=None)
    assert format_table(unvalidated, truth).splitlines()[2] == UNVALIDATED


def test_entries_in_rig_identify_order_with_truth_and_products_sign(answer):
    d, truth = answer
    text = format_table(d, truth)
    r = rows(text)
    assert list(r) == ["ixx", "iyy", "izz", "ixy", "ixz", "iyz"]
    J, Jt = d["inertia_about_cg"], truth["inertia_about_cg"]
    for k in KEYS:
        sign = 1.0 if k in ("ixx", "iyy", "izz") else -1.0     # products: vehicle-dynamics sign
        cells = r[k].split()
        assert float(cells[2]) == pytest.approx(sign * J[k], abs=0.006)          # identified
        assert float(cells[3]) == pytest.approx(d["inertia_std"][k], abs=0.006)  # ±1σ
        assert float(cells[4]) == pytest.approx(sign * Jt[k], abs=0.006)         # truth.yaml
    # the table's Iyz = −iyz (truth: iyz −102, so Iyz ≈ +102.7); the tensor's entries beside it
    iyz = float(r["iyz"].split()[2])
    assert iyz > 0 and abs(iyz + Jt["iyz"]) < 1.0
    line = next(x for x in text.splitlines() if x.startswith("the inertia tensor's off-diagonal entries"))
    assert float(line.split("iyz ")[1].split()[0]) == pytest.approx(J["iyz"], abs=0.006)


def test_undetermined_entry_prints_not_determined(answer):
    d, truth = answer
    d = copy.deepcopy(d)
    d["inertia_about_cg"]["ixy"] = d["inertia_std"]["ixy"] = None   # as in a not_identifiable answer
    text = format_table(d, truth)
    assert "not determined" in rows(text)["ixy"]
    assert "ixy not determined" in text
    assert float(rows(text)["ixx"].split()[2]) == pytest.approx(d["inertia_about_cg"]["ixx"], abs=0.006)


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


def test_the_table_says_sigma_leaves_out_the_given_mass_and_cg(answer):
    d, truth = answer
    text = format_table(d, truth)
    assert "mass and CG: the known values of rig.yaml" in text
    assert "taken as exact: the tensor's error from an error of the CG is not in its σ" in text


def test_the_rig_model_answer_reads_verdict_first_with_the_bound_and_the_cg_of_both_tests():
    """``mass_properties_client rig-model``'s text (``format_rig_model``) of a real answer: the
    JSON of ``rig-identify inertia --cg cg.json`` on the clean run (test_rigday's chain job, the
    identifier's ~/identify_rig_model answers the same object): the verdict first, each entry with
    σ and the bound, products with the vehicle-dynamics sign and their error against the truth,
    the CG of the static test, the run alone and both."""
    from rig_identification.nodes.client import format_rig_model
    res = json.loads(gather("rig_day_chain")["run"][1])
    truth = read_recording(recording("visible_case16_clean")).truth
    text = format_rig_model(res, truth)
    lines = text.splitlines()
    assert lines[2] == f"verdict: {res['verdict']}" and res["verdict"] == "ok"
    r = rows(text)
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
