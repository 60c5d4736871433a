"""Every output the docs show under ``<!-- output checked -->`` is what the code prints today
(test/doc_outputs.py: each document's commands run in its order in a scratch copy of the
repository's root; each shown line, found by its leading words, equals the real one).  A change
of the numbers that is meant: ``python test/doc_outputs.py --write``."""
import functools
import re
from pathlib import Path

import pytest
from doc_outputs import blocks, documents, match, numbers_agree, outputs, same

from rig_identification.model import experiment

BLOCKS = [b for path in documents() for b in blocks(path) if b.checked]


@functools.cache
def checked_outputs(path: Path) -> dict[int, str]:
    """The output of each command of ``path``'s checked blocks, run once for all its tests."""
    return outputs(path, ("checked",))


def test_the_readme_quick_start_and_the_tutorials_rig_model_fit_are_checked():
    def fits(name):
        return [c for b in BLOCKS if b.path.name == name for c in b.commands if "rig-identify inertia" in c.text]
    assert fits("README.md") and fits("tutorial.md")


@pytest.mark.parametrize("block", BLOCKS, ids=[f"{b.path.name}:{b.first + 1}" for b in BLOCKS])
def test_shown_output_is_todays(block):
    out = checked_outputs(block.path)
    pairs = [(c, shown, real) for c in block.commands for shown, real in match(c.shown, out[c.line])]
    assert pairs or block.commands[0].text.startswith("mkdir ")
    stale = [(c, shown, real) for c, shown, real in pairs if not same(shown, real)]
    assert not stale, (f"{block.path.name}:{block.first + 1}: the docs show lines the code no longer prints "
                       "(python test/doc_outputs.py --write refreshes them):\n"
                       + "\n".join(f"  $ {c.text}\n  shown {s}\n  real  {r}" for c, s, r in stale))


def test_the_experiment_file_format_in_the_docs_is_the_parsers():
    """docs/cli.md's experiment-file block is the schema that rig_identification.model.experiment
    documents beside the parser (its module docstring), line for line."""
    schema = re.search(r"Experiment file schema \(YAML\)\n-+\n::\n\n(.*?)\n\n", experiment.__doc__ + "\n\n", re.S)
    assert schema
    lines = [ln[4:] for ln in schema.group(1).splitlines()]
    doc = (Path(__file__).resolve().parent.parent / "docs" / "cli.md").read_text()
    shown = re.search(r"### Experiment files\n.*?```yaml\n(.*?)\n```", doc, re.S)
    assert shown and shown.group(1).splitlines() == lines


def test_a_shown_number_may_differ_by_one_unit_of_its_last_digit_and_nothing_else():
    assert same("Izz    3101.32   0.621   +0.5", "Izz    3101.31   0.621   +0.5")
    assert not same("Izz    3101.32   0.621   +0.5", "Izz    3101.30   0.621   +0.5")
    assert not same("Izz    3101.32   0.621   +0.5", "Izz    3101.3   0.621   +0.5")       # digits differ
    assert not numbers_agree("verdict: ok — 1 channel", "verdict: model_error — 1 channel")
    assert same("mass 1810.08 ± 0.19 kg ...", "mass 1810.07 ± 0.19 kg (the scale's value)")
    assert same("stiffness: 4.802e+06 N/m", "stiffness: 4.803e+06 N/m")
    assert not same("stiffness: 4.802e+06 N/m", "stiffness: 4.802e+07 N/m")             # the exponent counts


def test_a_number_printed_in_full_is_compared_to_its_7th_significant_digit():
    assert same("mass: 1810.0750056150403", "mass: 1810.075005")
    assert same("cg: [7.604167570888592e-05, 0.1]", "cg: [7.6041679e-05, 0.1]")
    assert not same("cg: [7.604167570888592e-05, 0.1]", "cg: [7.604169e-05, 0.1]")
    assert not same("mass: 1810.0750056150403", "mass: 1810.077")


def test_a_wall_time_is_not_compared_but_its_words_are():
    assert same("time: 19.6 s", "time: 128.9 s")
    assert not same("time: 19.6 s", "time: 128.9 ms")
