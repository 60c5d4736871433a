"""Every output the docs show under ``<!-- output checked -->`` is what the code prints today
(test/doc_outputs.py: each shown line, found by its leading words, equals the real one).  A
change of the numbers that is meant: ``python test/doc_outputs.py --write``."""
import re
from pathlib import Path

import pytest
from doc_outputs import blocks, documents, match, numbers_agree, run, same

from rig_identification.model import experiment

BLOCKS = [b for path in documents() for b in blocks(path) if b.checked]


def test_the_readme_quick_start_is_checked():
    assert any(b.path.name == "README.md" and b.argv[0] == "inertia" for b in BLOCKS)


@pytest.mark.parametrize("block", BLOCKS, ids=[f"{b.path.name}:{b.first + 1}" for b in BLOCKS])
def test_shown_output_is_todays(block):
    pairs = match(block.shown, run(block.argv))
    assert pairs
    stale = [(shown, real) for shown, real in pairs if not same(shown, real)]
    assert not stale, (f"{block.path.name}:{block.first + 1}: the docs show lines the code no longer prints "
                       "(python test/doc_outputs.py --write refreshes them):\n"
                       + "\n".join(f"  shown {s}\n  real  {r}" for s, r in stale))


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
