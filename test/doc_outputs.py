"""Shown outputs in the docs, checked against the code and refreshed from it.

A fenced block in README.md or docs/*.md preceded by the line ``<!-- output checked -->`` (or,
for commands too slow for the test suite, ``<!-- output refreshed -->``) holds commands, each a
line ``$ COMMAND`` followed by lines of its output, ``...`` standing for lines left out (and,
ending a line, for the rest of it).  A document's commands run in its order, each with bash, in
one scratch copy of the repository's root (its entries linked, ``../shared`` beside it, ``out/``
empty), so that a command finds the files the ones before it wrote and the user's ``out/`` is
not touched.  A block whose commands cannot run here (a ROS graph) is preceded by
``<!-- output not checked (WHY); made instead by: COMMAND -->``: COMMAND makes the files they
would, for the blocks after it.

Each shown line is found in its command's real output (standard output and error) by its
*key* — its words up to the first that holds a digit (``ixx``, ``mass``, ``verdict: ok — the
rigid-body model ...``) — in order, and must equal it, each number to one unit of its last digit
(another CPU's rounding moves the last digit of an iterative fit's result); a number printed in
full (more than 7 significant digits: a float as YAML, JSON or Python writes it) to one unit of
its 7th.  A wall time (a line whose key is ``time:``) is compared without its numbers.
test/test_doc_outputs.py checks every *checked* block; ``python test/doc_outputs.py`` checks
them all and ``--write`` rewrites the shown lines that differ from today's output (run it when a
change of the numbers is meant).
"""
from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("RIG_SHARED", REPO.parent / "shared"))
MARKERS = {"<!-- output checked -->": "checked", "<!-- output refreshed -->": "refreshed"}
INSTEAD = re.compile(r"<!-- output not checked \(.+?\); made instead by: (.+) -->")
PROMPT = "$ "
FULL = 7            # significant digits to which a number printed in full is compared
TIMED = ("time:",)  # keys of the lines that give a wall time


@dataclass(frozen=True)
class Command:
    """One command of a block: the index of its ``$`` line in the file, the command and the shown
    lines of its output."""

    line: int
    text: str
    shown: tuple[str, ...]


@dataclass(frozen=True)
class Block:
    """A marked block: its file, the index of its first line after the fence, its commands and its
    kind (``checked``, ``refreshed``, or ``instead``: not run, ``instead`` run in its place)."""

    path: Path
    first: int
    commands: tuple[Command, ...]
    kind: str
    instead: str | None = None

    @property
    def checked(self) -> bool:
        return self.kind == "checked"


def commands(lines: list[str], first: int, end: int) -> tuple[Command, ...]:
    """The commands of the block ``lines[first:end]``, each with the lines up to the next ``$``."""
    starts = [i for i in range(first, end) if lines[i].startswith(PROMPT)] + [end]
    return tuple(Command(i, lines[i][len(PROMPT):], tuple(lines[i + 1:j])) for i, j in zip(starts, starts[1:]))


def blocks(path: Path) -> list[Block]:
    """The marked blocks of a Markdown file."""
    lines = path.read_text().splitlines()
    out = []
    for i, line in enumerate(lines):
        marker, instead = line.strip(), INSTEAD.fullmatch(line.strip())
        if marker not in MARKERS and instead is None:
            continue
        if i + 2 >= len(lines) or not lines[i + 1].startswith("```") or not lines[i + 2].startswith(PROMPT):
            raise ValueError(f"{path}:{i + 1}: {marker} must precede a fenced block that starts with "
                             f"'{PROMPT}COMMAND'")
        end = next(j for j in range(i + 2, len(lines)) if lines[j].startswith("```"))
        if instead is not None:
            out.append(Block(path, i + 2, (), "instead", instead.group(1)))
        else:
            out.append(Block(path, i + 2, commands(lines, i + 2, end), MARKERS[marker]))
    return out


def key(line: str) -> str:
    """The words of ``line`` before the first that holds a digit (the whole line, less a closing
    `` ...``, if none)."""
    words = []
    for w in line.removesuffix(" ...").split():
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


NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def significant(x: str) -> int:
    """The number of significant digits of the number ``x`` as printed."""
    return len(x.lstrip("+-").partition("e")[0].replace(".", "").lstrip("0"))


def decimals(x: str) -> int:
    return len(x.partition("e")[0].partition(".")[2])


def numbers_agree(shown: str, real: str) -> bool:
    """The two texts are the same but for numbers that differ by at most one unit of the last digit
    shown (floating-point sums rounded differently by another CPU or BLAS build move the last
    digit of an iterative fit's result, not its meaning); a number printed in full (more than
    ``FULL`` significant digits) by at most one unit of its ``FULL``-th."""
    na, nb = NUMBER.findall(shown), NUMBER.findall(real)
    if len(na) != len(nb) or NUMBER.split(shown) != NUMBER.split(real):
        return False
    for x, y in zip(na, nb):
        if significant(x) > FULL:
            unit = 10.0 ** (math.floor(math.log10(abs(float(x)))) - FULL + 1)
        elif decimals(y) != decimals(x):
            return False
        else:
            unit = 10.0 ** (int(x.partition("e")[2] or 0) - decimals(x))
        if abs(float(x) - float(y)) > 1.01 * unit:
            return False
    return True


def same(shown: str, real: str | None) -> bool:
    """Whether the shown line is the real one (a shown line ending in `` ...`` is its beginning),
    numbers to one unit of their last digit (:func:`numbers_agree`), a wall time's not compared."""
    if real is None:
        return False
    if key(shown) in TIMED:
        return NUMBER.split(shown) == NUMBER.split(real)
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


def scratch(tmp: Path) -> Path:
    """A copy of the repository's root in ``tmp`` for the docs' commands: its entries linked but
    ``out/`` (and ``.git``), ``../shared`` beside it."""
    root = tmp / REPO.name
    root.mkdir()
    for entry in REPO.iterdir():
        if entry.name not in ("out", ".git"):
            (root / entry.name).symlink_to(entry)
    (tmp / "shared").symlink_to(SHARED)
    return root


#: One BLAS thread, as ``make test`` runs: a fit's last digits depend on the summation order that
#: the thread count sets, and the shown outputs are made and checked alike.
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def run(command: str, root: Path) -> str:
    """The command's standard output and error, interleaved as a terminal shows them, run by bash in
    ``root`` with one BLAS thread (:data:`ONE_THREAD`)."""
    done = subprocess.run(["bash", "-o", "pipefail", "-c", command], cwd=root, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, check=False, env={**os.environ, **ONE_THREAD})
    if done.returncode != 0:
        raise RuntimeError(f"{command} exited {done.returncode}: {done.stdout.strip()[-2000:]}")
    return done.stdout


def outputs(path: Path, kinds: tuple[str, ...] = ("checked", "refreshed")) -> dict[int, str]:
    """The output of each command of ``path``'s blocks of ``kinds`` (by the index of its line),
    the document's commands run in its order in one scratch root, each block marked ``instead``
    by its command."""
    out: dict[int, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = scratch(Path(tmp))
        for b in blocks(path):
            if b.instead is not None:
                run(b.instead, root)
            elif b.kind in kinds:
                for c in b.commands:
                    out[c.line] = run(c.text, root)
    return out


def write(path: Path, command: Command, output: str) -> None:
    """Rewrite the command's shown lines that differ from ``output``."""
    lines = path.read_text().splitlines()
    fresh = dict(match(command.shown, output))
    for i, line in enumerate(command.shown):
        new = fresh.get(line)
        if line.strip() != "..." and new is None:
            raise ValueError(f"{path}:{command.line + 2 + i}: no output line with the key {key(line)!r}")
        if new is not None and not same(line, new):
            lines[command.line + 1 + i] = as_shown(line, new)
    path.write_text("\n".join(lines) + "\n")


def documents() -> list[Path]:
    return [REPO / "README.md"] + sorted((REPO / "docs").glob("*.md"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="rewrite the shown lines that differ from today's output")
    args = ap.parse_args()
    bad = 0
    for path in documents():
        name = path.relative_to(REPO)
        out = outputs(path)
        for b in blocks(path):
            for c in b.commands:
                if args.write:
                    write(path, c, out[c.line])
                    continue
                for shown, real in match(c.shown, out[c.line]):
                    if not same(shown, real):
                        bad += 1
                        print(f"{name}:{c.line + 1}: shown  {shown}\n{' ' * len(str(name))}  real   {real}")
            if args.write and b.commands:
                print(f"{name}:{b.first + 1}: refreshed")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
