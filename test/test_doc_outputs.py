"""Every output the docs show under ``<!-- output checked -->`` is what the code prints today
(test/doc_outputs.py: each shown line, found by its leading words, equals the real one).  A
change of the numbers that is meant: ``python test/doc_outputs.py --write``."""
import pytest
from doc_outputs import blocks, documents, match, run, same

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
