"""The thesis's case studies, simulated noise-free, through `rig-identify thesis-table`
(pipeline.thesis_table.run_case): the rig model on the cases whose cables stretch, the thesis's
own method on every case.

The rig model: every entry within 0.1 % (of the entry for a moment, of the largest moment for a
product; the thesis reported up to 6 % and 22 % on these cases).  Durations are shortened to keep
the suite fast; ``rig-identify thesis-table`` runs every case at full length.
"""
import pytest
from conftest import background, gather

from rig_identification.pipeline.thesis_table import INEXTENSIBLE, run_case

background("thesis_cases", __file__, run_case, {"case10": ("case10", 30.0), "case16": ("case16", 30.0)})


@pytest.mark.parametrize("case", ["case10", "case16"])
def test_noise_free_case(case):
    """30 s of cases 10 and 16 (spring cables, 5 MN/m): the rig model within 0.1 % on every
    entry, verdict ok; the thesis's method (no gyroscopic term, forward Euler) gives an estimate."""
    row = gather("thesis_cases")[case]
    assert isinstance(row["ours"], dict), row["ours"]
    assert max(abs(v) for v in row["ours"].values()) < 0.1, row["ours"]
    assert row["ours_verdict"] == "ok"
    assert isinstance(row["thesis_model"], dict), row["thesis_model"]


def test_inextensible_and_pulse_cases_go_through_the_table_with_the_thesis_method():
    """The thesis's 10 s pulse case 4 (inextensible cables, the identification on the free
    motion after the pulses) and its free-swing case 1: the thesis's method gives an estimate
    within its own reported error on every moment; the rig model says why it is not run
    (inextensible cables are outside its physics) instead of failing."""
    for name in ("case01", "case04"):
        row = run_case(name)
        assert row["ours"] == INEXTENSIBLE, row["ours"]
        assert isinstance(row["thesis_model"], dict), row["thesis_model"]
        reported = row["thesis_reported"]
        for k in ("ixx", "iyy", "izz"):
            assert abs(row["thesis_model"][k]) <= max(reported[k][0], 0.05), (name, k, row["thesis_model"], reported)
