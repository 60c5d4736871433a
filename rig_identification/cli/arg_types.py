"""argparse types and shared option tables of ``rig-identify``: light (no numpy), so that the
top-level parser (:mod:`rig_identification.cli.main`) builds without the heavy modules."""
from __future__ import annotations

import argparse
import math


class UsageError(ValueError):
    """A command line that cannot run: a path that does not exist, an output that cannot be
    written, options that do not go together.  Names the path or the option."""


def number(name: str, zero: bool = False):
    """argparse type of option ``name``: a finite number > 0 (``zero``: >= 0); anything else
    is an argparse error naming the option."""
    def f(text):
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not (math.isfinite(x) and (x >= 0 if zero else x > 0)):
            raise argparse.ArgumentTypeError(f"{name} must be {'>=' if zero else '>'} 0, got {text!r}")
        return x
    return f


#: ``inertia``'s report header options: (flag, argparse dest, what the text names).
JOB_OPTIONS = (("--vehicle-name", "vehicle_name", "the vehicle measured (make, model, VIN)"),
               ("--customer", "customer", "the customer"),
               ("--operator", "operator", "who ran the test"))

__all__ = ["JOB_OPTIONS", "number"]
