"""Shown outputs in the docs, checked against the code and refreshed from it.

A fenced block in README.md or docs/*.md preceded by the line ``<!-- output checked -->`` (or,
for a command too slow for the test suite, ``<!-- output refreshed -->``) holds
one command (``$ .venv/bin/rig-identify ...``, run from the repository's root) and lines of
its output, ``...`` standing for lines left out (and, ending a line, for the rest of it).
Each shown line is found in the command's
real output by its *key* — its words up to the first that holds a digit (``ixx``, ``mass``,
``verdict: ok — the rigid-body model ...``) — in order, and must equal it, each number to one
unit of its last digit (another CPU's rounding moves the last digit of an iterative fit's result).
test/test_doc_outputs.py checks every *checked* block; ``python test/doc_outputs.py`` checks
them all and ``--write`` rewrites every block's shown lines from today's output (run it when a
change of the numbers is meant).
"""
from __future__ import annotations

import argparse
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
MARKERS = {"<!-- output checked -->": True, "<!-- output refreshed -->": False}
PROGRAM = ".venv/bin/rig-identify"


@dataclass(frozen=True)
class Block:
    """A checked block: its file, the index of its first line after the fence, the command's
    arguments (after the program) and the shown lines (command line excluded)."""

    path: Path
    first: int
    argv: tuple[str, ...]
    shown: tuple[str, ...]
    checked: bool


def blocks(path: Path) -> list[Block]:
    """The checked blocks of a Markdown file."""
    lines = path.read_text().splitlines()
    out = []
    for i, line in enumerate(lines):
        if line.strip() not in MARKERS:
            continue
        if i + 2 >= len(lines) or not lines[i + 1].startswith("```") or not lines[i + 2].startswith(f"$ {PROGRAM} "):
            raise ValueError(f"{path}:{i + 1}: {line.strip()} must precede a fenced block that starts with "
                             f"'$ {PROGRAM} ...'")
        end = next(j for j in range(i + 2, len(lines)) if lines[j].startswith("```"))
        argv = tuple(shlex.split(lines[i + 2][len(f"$ {PROGRAM} "):]))
        out.append(Block(path, i + 2, argv, tuple(lines[i + 3:end]), MARKERS[line.strip()]))
    return out


def key(line: str) -> str:
    """The words of ``line`` before the first that holds a digit (the whole line if none)."""
    words = []
    for w in line.split():
        if re.search(r"\d", w):
            break
        words.append(w)
    return " ".join(words)


def match(shown: tuple[str, ...], output: str) -> list[tuple[str, str | None]]:
    """Each shown line (``...`` skipped) with the output line of the same key found after the
    previous one's (None where there is none)."""
    real = output.splitlines()
    pos = 0
    pairs: list[tuple[str, str | None]] = []
    for line in shown:
        if line.strip() == "...":
            continue
        k = key(line)
        j = next((j for j in range(pos, len(real)) if key(real[j]) == k), None)
        pairs.append((line, None if j is None else real[j]))
        if j is not None:
            pos = j + 1
    return pairs


NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?")


def numbers_agree(shown: str, real: str) -> bool:
    """The two texts are the same but for numbers that differ by at most one unit of the last digit
    shown (floating-point sums rounded differently by another CPU or BLAS build move the last
    digit of an iterative fit's result, not its meaning)."""
    na, nb = NUMBER.findall(shown), NUMBER.findall(real)
    if len(na) != len(nb) or NUMBER.split(shown) != NUMBER.split(real):
        return False
    for x, y in zip(na, nb):
        digits = len(x.partition(".")[2])
        if len(y.partition(".")[2]) != digits or abs(float(x) - float(y)) > 1.01 * 10.0 ** -digits:
            return False
    return True


def same(shown: str, real: str | None) -> bool:
    """Whether the shown line is the real one (a shown line ending in `` ...`` is its beginning),
    numbers to one unit of their last digit (:func:`numbers_agree`)."""
    if real is None:
        return False
    if shown.endswith(" ..."):
        head = shown[:-4]
        return real.startswith(head) or numbers_agree(head, real[:len(head)])
    return shown == real or numbers_agree(shown, real)


def as_shown(shown: str, real: str) -> str:
    """The real line as the docs show it: cut after as many words as the shown one has where it ends in `` ...``."""
    if not shown.endswith(" ..."):
        return real
    words = len(shown[:-4].split(" "))
    return " ".join(real.split(" ")[:words]) + " ..."


def run(argv: tuple[str, ...]) -> str:
    """The command's standard output and error, interleaved as a terminal shows them, run as a process from
    the repository's root."""
    done = subprocess.run([str(REPO / PROGRAM), *argv], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"{PROGRAM} {' '.join(argv)} exited {done.returncode}: {done.stdout.strip()[-2000:]}")
    return done.stdout


def write(block: Block, output: str) -> None:
    """Rewrite the block's shown lines from ``output``."""
    lines = block.path.read_text().splitlines()
    fresh = dict(match(block.shown, output))
    for i, line in enumerate(block.shown):
        new = fresh.get(line)
        if line.strip() != "..." and new is None:
            raise ValueError(f"{block.path}:{block.first + 2 + i}: no output line with the key {key(line)!r}")
        if new is not None:
            lines[block.first + 1 + i] = as_shown(line, new)
    block.path.write_text("\n".join(lines) + "\n")


def documents() -> list[Path]:
    return [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="rewrite the shown lines from today's output")
    args = ap.parse_args()
    bad = 0
    for path in documents():
        for b in blocks(path):
            out = run(b.argv)
            if args.write:
                write(b, out)
                print(f"{path.relative_to(REPO)}:{b.first + 1}: refreshed")
                continue
            for shown, real in match(b.shown, out):
                if not same(shown, real):
                    bad += 1
                    print(f"{path.relative_to(REPO)}: shown  {shown}\n{' ' * len(str(path.relative_to(REPO)))}  "
                          f"real   {real}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
