"""A node's process: ``--help``, rclpy set-up, the executor, spinning, a bounded shutdown.

Executor: :func:`spin` runs a node on ``rclpy.experimental.EventsExecutor`` (parameter
``executor``: ``events`` (default) or ``single``).  In the pip build of rclpy 7.1.6 the
EventsExecutor's blocking ``spin()``/``spin_once()`` without a timeout hang (no callback
runs), while the timed variants work; :func:`spin` therefore spins in slices of 1 s.
That rclpy also does not support ``async`` service callbacks on the EventsExecutor
(fixed upstream in rclpy 7.1.11), see ``identifier_node`` for how the identifier copes.
"""
from __future__ import annotations

import faulthandler
import os
import re
import sys
import threading
import time
from typing import Callable

import rclpy
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.task import Future

from ..io.rig import RigError
from ..io.verdict import PACKAGE, package_version
from .environment import dds_profile

# reStructuredText inline markup of the modules' docstrings: :role:`title <target>`,
# :role:`~a.b.name`, :role:`name`, ``literal``
_ROLE_TITLED = re.compile(r":[a-z]+:`([^`<]+?)\s*<[^`>]+>`")
_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")
_LITERAL = re.compile(r"``([^`]+)``")


def plain_text(doc: str) -> str:
    """``doc`` (a module docstring, reStructuredText) as plain text for a terminal: roles
    become their title or target (``:class:`~a.b.C``` -> ``C``), ``literals`` their text."""
    doc = _ROLE_TITLED.sub(r"\1", doc)
    doc = _ROLE.sub(lambda m: m.group(1).rsplit(".", 1)[-1] if m.group(0).count("~") else m.group(1), doc)
    return _LITERAL.sub(r"\1", doc)


def handle_help(argv: list[str] | None, prog: str, doc: str) -> list[str]:
    """Print the node's documentation (:func:`plain_text`) and exit 0 on ``-h``/``--help``, its
    version on ``--version`` (before any ROS set-up).

    ROS arguments (after ``--ros-args``) are left for ``rclpy.init``.  Returns ``argv``.
    """
    argv = list(sys.argv if argv is None else argv)
    user = argv[1:argv.index("--ros-args")] if "--ros-args" in argv else argv[1:]
    if "-h" in user or "--help" in user:
        print(f"usage: {prog} [--ros-args -p NAME:=VALUE ... | --params-file FILE]\n")
        print(plain_text(doc).strip())
        raise SystemExit(0)
    if "--version" in user:
        print(f"{prog} ({PACKAGE}) {package_version()}")
        raise SystemExit(0)
    unknown = [a for a in user if a.startswith("-")]
    if unknown:
        print(f"{prog}: error: unknown option(s) {' '.join(unknown)} "
              "(node parameters go after --ros-args, e.g. --ros-args -p rate:=2.0; see --help)",
              file=sys.stderr)
        raise SystemExit(2)
    return argv


def make_executor(kind: str):
    if kind == "events":
        return EventsExecutor()
    if kind == "single":
        return SingleThreadedExecutor()
    if kind == "multi":
        return MultiThreadedExecutor()
    raise ValueError(f"parameter executor = {kind!r}: expected 'events', 'single' or 'multi'")


def spin(node: Node, stop=None) -> None:
    """Spin ``node`` until Ctrl-C / SIGTERM (rclpy's signal handler shuts the context down)
    or until the rclpy Future ``stop`` completes.  Executor from the node's ``executor``
    parameter (declared here when the node has not), default EventsExecutor."""
    if not node.has_parameter("executor"):
        node.declare_parameter("executor", "events")
    kind = node.get_parameter("executor").value
    ex = make_executor(kind)
    ex.add_node(node)
    stop = Future() if stop is None else stop
    try:
        while rclpy.ok() and not stop.done():
            # timed slices: the EventsExecutor of rclpy 7.1.6 hangs in untimed spins
            ex.spin_until_future_complete(stop, timeout_sec=1.0)
    except KeyboardInterrupt:
        pass
    except Exception as e:  # ExternalShutdownException and friends at shutdown
        if rclpy.ok():
            raise
        del e
    finally:
        try:
            ex.shutdown()
        except Exception:
            pass


#: s a node may take to finish after rclpy's context is shut down (Ctrl-C, SIGTERM)
SHUTDOWN_GRACE = 8.0


def shutdown_watchdog(prog: str, grace: float = SHUTDOWN_GRACE) -> None:
    """Daemon thread: once rclpy's context is shut down (the node was told to stop), give
    the node ``grace`` s to finish; if it has not, print every thread's stack on stderr (to
    find the hang) and end the process with status 0 — the stop was requested, and results
    are written atomically (:mod:`..atomic`), so nothing is half-written.  Guards against a
    rare hang of the executor at shutdown (seen once in CI: the tracker did not exit within
    15 s of SIGINT)."""
    def watch():
        while rclpy.ok():
            time.sleep(0.2)
        time.sleep(grace)
        print(f"{prog}: shutdown did not finish within {grace:g} s of the stop request; exiting "
              "(thread stacks follow)", file=sys.stderr, flush=True)
        faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        sys.stderr.flush()
        os._exit(0)

    threading.Thread(target=watch, name="shutdown-watchdog", daemon=True).start()


def run(node_factory: Callable[[], Node], argv: list[str] | None, prog: str, doc: str) -> int:
    """Standard ``main`` of a node: help, rclpy init, construct, spin, clean shutdown
    (bounded: :func:`shutdown_watchdog`).

    A start-up error that the user can fix (bad rig.yaml, missing file, bad parameter)
    prints one line on stderr and returns 2, no traceback.
    """
    argv = handle_help(argv, prog, doc)
    dds_profile()
    rclpy.init(args=argv)
    shutdown_watchdog(prog)
    node = None
    try:
        try:
            node = node_factory()
        except (RigError, ValueError, OSError, RuntimeError) as e:  # SimulationError too
            print(f"{prog}: error: {e}", file=sys.stderr)
            return 2
        spin(node, getattr(node, "stop_future", None))
        return int(getattr(node, "exit_code", 0))
    except KeyboardInterrupt:
        return 0
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()


class BackgroundSpin:
    """Spin ``executor`` (with ``node`` added) in a daemon thread until :meth:`close`, which
    then shuts the executor down, destroys the node and shuts ``context`` down.  The
    listening side of a tool that watches the graph from its own process and context (the
    demo's monitor, the node tests, the load benchmark); the nodes themselves spin in
    their main thread."""

    def __init__(self, executor, node, context):
        self.executor, self.node, self.context = executor, node, context
        executor.add_node(node)
        self._never = Future()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._stop.is_set() and self.context.ok():
            try:
                self.executor.spin_until_future_complete(self._never, timeout_sec=0.1)
            except Exception:
                if self.context.ok():
                    raise

    def close(self):
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()
