"""The window of a fit over buffered streams (the identifier node's ``~/identify_rig_model``): the
window asked for, a settling time, and the gaps in the input streams.

A gap is what :func:`~rig_identification.io.quality.find_bad_spans` calls one offline: two
consecutive stamps of a stream further apart than max(0.1 s, 1.5 sampling periods) (a sensor
that stopped).  No fit runs over one: a window that contains a gap is refused, naming the stream
and the span; a window that only ends or starts inside one is cut at its edge; with no window
start or end asked for, the fit uses the data after the last gap plus ``settle_after_gap``.
Stamps in s.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

Gap = tuple[str, float, float]
"""A gap: (stream, stamp of its last sample before, stamp of its first sample after), s."""


class FitWindowError(ValueError):
    """No window to fit: too little data, or a gap inside the window asked for."""


@dataclass(frozen=True)
class FitWindow:
    """The window of a fit: ``start``, ``end`` stamps s; ``notes``: what moved it (edges cut at a
    gap, the data after a gap), for the answer's warnings."""

    start: float
    end: float
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class WindowRequest:
    """The window a fit asks for (the identifier's parameters), s after the first IMU sample.

    start, end: the window (None: from the start, to the latest sample); last: only the last
    ``last`` s of it (None: all of it); settle: the window never starts earlier; settle_after_gap:
    with no ``start`` or ``end``, the fit starts this long after the last gap; min_duration: a
    shorter window is refused.
    """

    start: float | None = None
    end: float | None = None
    last: float | None = None
    settle: float = 0.0
    settle_after_gap: float = 0.0
    min_duration: float = 10.0


def describe_gaps(gaps: list[Gap], t0: float, most: int = 4) -> str:
    """"no data on TOPIC from t=A to B s ..." for the gaps (by time), times after ``t0``."""
    gaps = sorted(gaps, key=lambda g: (g[1], g[0]))
    text = "; ".join(f"no data on {topic} from t={a - t0:.2f} to {b - t0:.2f} s ({b - a:.2f} s)"
                     for topic, a, b in gaps[:most])
    more = f" (and {len(gaps) - most} more)" if len(gaps) > most else ""
    return f"{text}{more} (times after the first IMU sample)"


def fit_window(t_first: float, t_last: float, gaps_in: Callable[[float, float], list[Gap]],
               asked: WindowRequest = WindowRequest()) -> FitWindow:
    """The window of a fit over streams buffered from ``t_first`` (the first IMU sample) to
    ``t_last`` (the latest sample), stamps s, for the window ``asked`` (:class:`WindowRequest`).

    gaps_in(lo, hi): the gaps of the input streams overlapping [lo, hi] (a stream silent until
    ``hi`` counts as a gap up to it).  Gaps as the module docstring says.  Raises
    :class:`FitWindowError`: a gap inside the window asked for, or less than ``min_duration`` s of
    data (the message names the window, s after ``t_first``).
    """
    t0 = t_first
    lo = t0 + max(asked.start if asked.start is not None else 0.0, asked.settle)
    hi = t_last if asked.end is None else min(t0 + asked.end, t_last)
    if asked.last is not None:
        lo = max(lo, hi - asked.last)
    gaps = gaps_in(lo, hi)
    notes = []
    # a window that ends (starts) inside a gap ends (starts) at its edge: no data there anyway
    for topic, a, b in gaps:
        if a < hi <= b and a > lo:
            hi = a
            notes.append(f"window end moved to t={hi - t0:.2f} s, where {topic} stops")
        if a <= lo < b and b < hi:
            lo = b
            notes.append(f"window start moved to t={lo - t0:.2f} s, where {topic} resumes")
    gaps = gaps_in(lo, hi) if notes else gaps
    if gaps and asked.start is None and asked.end is None:
        # no window asked for: the data after the last gap (a sensor that stopped)
        after = max(b for _, _, b in gaps) + asked.settle_after_gap
        notes.append(f"gap in the data: {describe_gaps(gaps, t0)}; the fit uses the data after it "
                     f"(from t={after - t0:.1f} s, settle_after_gap {asked.settle_after_gap:g} s included)")
        lo = after
        gaps = gaps_in(lo, hi)
    if gaps:
        raise FitWindowError(f"the window t={lo - t0:.1f} to {hi - t0:.1f} s contains a gap: "
                             f"{describe_gaps(gaps, t0)}; no fit over missing data: choose a window "
                             "without it (window_start / window_end / window_last)")
    if hi - lo < asked.min_duration:
        raise FitWindowError(f"the window holds {max(hi - lo, 0.0):.1f} s of data "
                             f"({lo - t0:.1f} to {hi - t0:.1f} s after the first IMU sample); "
                             f"min_duration is {asked.min_duration:g} s: wait for more data or widen the window"
                             + (f" [{notes[0]}]" if notes else ""))
    return FitWindow(lo, hi, tuple(notes))
