"""Shared helpers of the test suite.

Background jobs: a module whose tests rest on heavy, self-contained computations (simulations
and fits that return plain data) declares them with :func:`background` when it is imported,
and its fixtures take the results with :func:`gather`.  Once collection is done, the jobs of
the selected modules start in ``RIG_TEST_WORKERS`` worker processes (default 1: the
machine's second core) while the other modules' tests run in this process, and the modules
that declared jobs run last, in the reverse order of their jobs: the workers take the jobs
from the front (the ``first`` groups, then in the order declared), and :func:`gather` computes
here whatever no worker has started yet, so the two meet in the middle.
``RIG_TEST_WORKERS=0`` computes everything in this process, at the fixture.  What is
computed, and what is asserted on it, is the same either way.

The workers run niced (``RIG_TEST_WORKER_NICE``, default 10): they take a core nobody else
needs, and yield it to the tests that replay recordings in real time over DDS (their nodes'
timing) and to other users of the machine; once the modules with jobs begin (the last), the
workers get this process's priority back where the system allows it.
"""
import contextlib
import io
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest

from rig_identification.cli.main import identify_main

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("RIG_SHARED", REPO.parent / "shared"))
RECORDINGS = SHARED / "recordings"
# one worker (the machine's second core; RIG_TEST_WORKERS to change it): with one per core the
# workers' simulations and the DDS graph's 4 node processes and listener oversubscribed the
# 2 cores: in a full run every graph test of test_nodes timed out waiting for the pipeline to
# drain (the test's listener had 5815 of the 5980 poses after 120 s)
WORKERS = int(os.environ.get("RIG_TEST_WORKERS", "1"))
WORKER_NICE = int(os.environ.get("RIG_TEST_WORKER_NICE", "10"))


def run_cli(*argv) -> tuple[int, str, str]:
    """``rig-identify`` in this process (``identify_main``): (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = identify_main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def recording(name: str) -> Path:
    p = RECORDINGS / name
    if not p.exists():
        pytest.fail(f"reference recording {p} is missing (../shared/recordings must sit beside the repository)")
    return p


_groups: dict = {}      # group -> (module file, {key: (fn, args)}), in the order the workers take them
_futures: dict = {}     # group -> {key: Future}, when a worker pool took them
_done: dict = {}        # group -> {key: result} taken by gather
_seconds: dict = {}     # (group, key) -> wall seconds the job took, where and when it ran (the terminal summary)


def _timed(fn, *args):
    """``(fn(*args), wall seconds)``: a job as a worker or :func:`gather` runs it."""
    t = time.perf_counter()
    return fn(*args), time.perf_counter() - t
_first: set = set()   # the groups declared with first=True
_pool = None


def background(group: str, module_file: str, fn, jobs: dict, first: bool = False) -> None:
    """Declare the jobs of ``group`` (``{key: args}``; each is ``fn(*args)``, ``fn`` a
    module-level function returning picklable data) for the module ``module_file``.  List
    the longest first; ``first``: before the groups declared without it (the longest jobs of
    the suite, so that none is left alone at the end)."""
    entry = (str(Path(module_file).resolve()), {k: (fn, tuple(a)) for k, a in jobs.items()})
    if first:
        items = list(_groups.items())
        items.insert(len(_first), (group, entry))
        _groups.clear()
        _groups.update(items)
        _first.add(group)
    else:
        _groups[group] = entry


def gather(group: str, *keys) -> dict:
    """``{key: fn(*args)}`` of ``group``'s jobs (those of ``keys``, default all): the ones no
    worker has started are computed here (from the last, one at a time, so that the workers
    keep taking the first ones), then the workers' results are waited for."""
    _hurry()
    _, jobs = _groups[group]
    keys = list(keys or jobs)
    futures = _futures.get(group, {})
    out = _done.setdefault(group, {})
    for key in reversed(keys):
        if key in out:
            continue
        f = futures.get(key)
        if f is None or f.cancel():
            fn, args = jobs[key]
            out[key], _seconds[group, key] = _timed(fn, *args)
    for key in keys:
        if key not in out:
            out[key], _seconds[group, key] = futures[key].result()
    return {key: out[key] for key in keys}


def _niced():
    """Worker initializer: a lower priority than the tests'."""
    os.nice(WORKER_NICE)


def _hurry():
    """The modules with jobs have begun (they run last: no real-time test is left) and this
    process may wait for the workers: they get its priority back (lowering a niceness needs
    the privilege; without it they stay niced)."""
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    for p in list((_pool._processes or {}).values()) if _pool is not None else []:
        try:
            if os.getpriority(os.PRIO_PROCESS, p.pid) > mine:
                os.setpriority(os.PRIO_PROCESS, p.pid, mine)
        except (PermissionError, ProcessLookupError):
            pass


def _module(item) -> str:
    return str(Path(item.path).resolve())


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(session, config, items):
    """The modules with background jobs run last, the one whose jobs the workers take last first."""
    order: dict = {}
    for i, (mod, _) in enumerate(_groups.values()):
        order.setdefault(mod, i)
    items.sort(key=lambda it: -order.get(_module(it), len(_groups)))


def pytest_collection_finish(session):
    global _pool
    if WORKERS <= 0 or session.config.option.collectonly:
        return
    selected = {_module(it) for it in session.items}
    todo = [(group, jobs) for group, (mod, jobs) in _groups.items() if mod in selected]
    if not todo:
        return
    # forked now, before any test has started a thread (rclpy, DDS)
    _pool = ProcessPoolExecutor(WORKERS, mp_context=multiprocessing.get_context("fork"), initializer=_niced)
    for group, jobs in todo:
        _futures[group] = {key: _pool.submit(_timed, fn, *args) for key, (fn, args) in jobs.items()}


def pytest_terminal_summary(terminalreporter):
    """The background jobs' wall times, longest first (where the suite's time goes besides the
    tests' own, which ``--durations`` lists)."""
    if _seconds:
        terminalreporter.write_sep("-", "background jobs (wall s)")
        for (group, key), s in sorted(_seconds.items(), key=lambda kv: -kv[1]):
            terminalreporter.write_line(f"{s:7.1f}  {group}/{key}")


def pytest_sessionfinish(session, exitstatus):
    """Stop the workers (a session cut short by -x or Ctrl-C does not wait for their jobs)."""
    if _pool is None:
        return
    procs = list((_pool._processes or {}).values())
    _pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
        p.join(timeout=10)
