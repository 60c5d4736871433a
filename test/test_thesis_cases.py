"""Issue 2: simulated thesis case studies, noise-free, through the whole offline pipeline.

Every diagonal entry within 0.1 % and every product within 0.1 % of the largest diagonal
(the thesis reported up to 6 % and 22 % on these cases).  Durations are shortened to
keep the suite fast; bench/bench_thesis_cases.py runs all of 10–17 at full length.
"""
from dataclasses import replace
from pathlib import Path

import pytest

from rig_identification.estimation.inertia_result import compare_to_truth
from rig_identification.io.recording import Recording
from rig_identification.model.experiment import load_experiment
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.offline import identify_recording

CASES = Path(__file__).resolve().parents[1] / "config" / "cases"


@pytest.mark.parametrize("case", ["case10", "case16"])
def test_noise_free_case(case):
    # 30 s: the largest error 0.036 % (case 10) and 0.0017 % (case 16) of the 0.1 % (60 s:
    # 0.021 % and 0.0002 %; case 10 wanders 0.02–0.04 % between 30 and 60 s)
    exp = load_experiment(CASES / f"{case}.yaml")
    sim = simulate(replace(exp, duration=30.0))
    res = identify_recording(Recording(sim.rig, sim.sensors, sim.truth))  # noise-free
    for k, c in compare_to_truth(res, sim.truth).items():
        assert abs(c["error_percent"]) < 0.1, (case, k, c)


def test_pulse_cases_run_through_the_table():
    """The thesis's 10 s pulse cases (noise-free stepped forces held exactly — not a saturated
    sensor) go through `rig-identify thesis-table` with both models, within the issue's
    0.05 %: case 4 (identification on the free motion after the pulses), cases 1 and 2 (the
    pulses themselves, sampled at 100 Hz without anti-aliasing; the thesis: 0.4–8 %)."""
    from rig_identification.pipeline.thesis_table import run_case
    for name, bound in (("case04", 0.05), ("case01", 0.05), ("case02", 0.05), ("case07", 0.05)):
        row = run_case(name)
        assert isinstance(row["ours"], dict) and isinstance(row["thesis_model"], dict), row
        assert all(abs(v) < bound for v in row["ours"].values()), (name, row["ours"])
