"""What ``rig-identify`` is doing, on stderr, as it happens: one line per step, warnings at once.

The core modules say what they are doing through Python's :mod:`logging`, under the
``rig_identification`` logger: an INFO record starts a step ("tracking the pose"), a WARNING
record is a warning to show now.  :class:`StepPrinter` is the handler the command line attaches
(:func:`attached`): it prints ``rig-identify: tracking the pose …`` when a step starts and its
duration (`` 2.8 s``) when the next one starts or the command ends, and ``warning: …`` lines
as they come; ``--quiet`` keeps the steps off and the warnings on.  A heading (:func:`heading`:
a record with ``extra={"heading": True}``) names a stage made of the steps that follow it: it
prints ``rig-identify: identifying (…):`` on a line of its own, without a duration (it would
read 0.0 s: the stage's time is that of its steps).  Without the handler (a
library user, a node) the records go where the application's logging sends them.
"""
from __future__ import annotations

import logging
import sys
import time
from contextlib import contextmanager

LOGGER = "rig_identification"


class StepPrinter(logging.Handler):
    """Prints steps and warnings of the ``rig_identification`` loggers on ``sys.stderr`` (looked
    up at each record, so that a captured stderr captures them).

    quiet: no step lines; prog: the prefix of step lines.  ``shown`` holds the warnings printed,
    so that the command's closing list of warnings (the result's) does not print them twice."""

    def __init__(self, quiet: bool = False, prog: str = "rig-identify"):
        super().__init__(logging.INFO)
        self.quiet = quiet
        self.prog = prog
        self.shown: set[str] = set()
        self._step: str | None = None
        self._t0 = 0.0
        self._partial = False     # the step's line is on screen without its duration yet

    def _write(self, text: str) -> None:
        sys.stderr.write(text)
        sys.stderr.flush()

    def _close_step(self) -> None:
        if self._step is None:
            return
        dt = f"{time.monotonic() - self._t0:.1f} s"
        self._write(f" {dt}\n" if self._partial else f"{self.prog}: {self._step} … {dt}\n")
        self._step, self._partial = None, False

    def emit(self, record: logging.LogRecord) -> None:
        try:
            msg = record.getMessage()
            if record.levelno >= logging.WARNING:
                if self._partial:          # finish the open step's line first
                    self._write("\n")
                    self._partial = False
                self._write(f"warning: {msg}\n")
                self.shown.add(msg)
            elif not self.quiet and getattr(record, "heading", False):
                self._close_step()
                self._write(f"{self.prog}: {msg.rstrip(' .…:')}:\n")
            elif not self.quiet:
                self._close_step()
                msg = msg.rstrip(" .…")     # "simulating the baseline ..." -> one ellipsis, ours
                self._step, self._t0, self._partial = msg, time.monotonic(), True
                self._write(f"{self.prog}: {msg} …")
        except Exception:   # noqa: BLE001 — logging's own contract: a handler never raises
            self.handleError(record)

    def finish(self) -> None:
        """Close the last step (print its duration)."""
        self._close_step()

    def fail(self) -> None:
        """Close the last step as failed (an error follows)."""
        if self._step is not None:
            dt = f"failed after {time.monotonic() - self._t0:.1f} s"
            self._write(f" {dt}\n" if self._partial else f"{self.prog}: {self._step} … {dt}\n")
            self._step, self._partial = None, False

    def warn_rest(self, warnings) -> None:
        """Print the warnings of ``warnings`` not shown yet (``warning: …``)."""
        for w in warnings:
            if w not in self.shown:
                self.emit(logging.LogRecord(LOGGER, logging.WARNING, __file__, 0, w, None, None))


@contextmanager
def attached(quiet: bool = False, prog: str = "rig-identify"):
    """Attach a :class:`StepPrinter` (its lines prefixed ``prog:``) to the ``rig_identification``
    logger (level INFO) for the duration of the block; yields it.  The last step is closed on
    the way out."""
    log = logging.getLogger(LOGGER)
    printer = StepPrinter(quiet, prog)
    old_level = log.level
    log.addHandler(printer)
    log.setLevel(logging.INFO)
    try:
        yield printer
    finally:
        printer.finish()
        log.removeHandler(printer)
        log.setLevel(old_level)


def step(message: str) -> None:
    """Start a step of the command line itself (``rig_identification.cli.main`` logger, INFO)."""
    logging.getLogger(LOGGER + ".cli").info(message)


def heading(message: str) -> None:
    """Name a stage of the command line whose steps follow (printed without a duration)."""
    logging.getLogger(LOGGER + ".cli").info(message, extra={"heading": True})


def warn(message: str) -> None:
    """A warning of the command line itself, shown at once (WARNING)."""
    logging.getLogger(LOGGER + ".cli").warning(message)
