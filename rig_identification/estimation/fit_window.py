"""The window of a fit over buffered streams (the identifier node's ``~/identify_inertia``): the
window asked for, the tracker's settling time, and the gaps in the input streams.

A gap is what :func:`~rig_identification.io.bad_spans.find_bad_spans` calls one offline: two
consecutive stamps of a stream further apart than max(0.1 s, 1.5 sampling periods) (a sensor or
a node that stopped).  No fit runs over one: a window that contains a gap is refused, naming the
stream and the span; a window that only ends or starts inside one is cut at its edge; with no
window asked for, the fit uses the data after the last gap plus ``settle_after_gap`` (a tracker
re-initialised on the moving body needs that long to forget its start; the offline replay
re-initialises it on the clean span instead).  Stamps in s.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Collection

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


def describe_gaps(gaps: list[Gap], t0: float, derived: Collection[str] = (), most: int = 4) -> str:
    """"no data on TOPIC from t=A to B s ..." for the gaps, times after ``t0``; the streams in
    ``derived`` (computed from the others, e.g. the generalized wrench) last: their gaps follow
    from the sensors'."""
    gaps = sorted(gaps, key=lambda g: (g[0] in derived, g[1]))
    text = "; ".join(f"no data on {topic} from t={a - t0:.2f} to {b - t0:.2f} s ({b - a:.2f} s)"
                     for topic, a, b in gaps[:most])
    more = f" (and {len(gaps) - most} more)" if len(gaps) > most else ""
    return f"{text}{more} (times after the first IMU sample)"


def fit_window(t_first: float, t_last: float, gaps_in: Callable[[float, float], list[Gap]],
               start: float | None = None, end: float | None = None, last: float | None = None,
               settle: float = 5.0, settle_after_gap: float = 20.0, min_duration: float = 10.0,
               derived: Collection[str] = ()) -> FitWindow:
    """The window of a fit over streams buffered from ``t_first`` (the first IMU sample) to
    ``t_last`` (the latest sample of the fitted stream), stamps s.

    start, end: the window asked for, s after ``t_first`` (None: from the start, to the
    latest); last: only the last ``last`` s of it.  The window never starts before
    ``t_first + settle``.  gaps_in(lo, hi): the gaps of the input streams overlapping [lo, hi]
    (a stream silent until ``hi`` counts as a gap up to it).  Gaps as the module docstring
    says.  Raises :class:`FitWindowError`: a gap inside the window asked for, or less than
    ``min_duration`` s of data (the message names the window, s after ``t_first``).
    """
    t0 = t_first
    lo = t0 + max(start if start is not None else 0.0, settle)
    hi = t_last if end is None else min(t0 + end, t_last)
    if last is not None:
        lo = max(lo, hi - last)
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
    if gaps and start is None and end is None and last is None:
        # no window asked for: the data after the last gap (a sensor or node that stopped)
        after = max(b for _, _, b in gaps) + settle_after_gap
        notes.append(f"gap in the data: {describe_gaps(gaps, t0, derived)}; the fit uses the data after it "
                     f"(from t={after - t0:.1f} s, settle_after_gap {settle_after_gap:g} s included)")
        lo = after
        gaps = gaps_in(lo, hi)
    if gaps:
        raise FitWindowError(f"the window t={lo - t0:.1f} to {hi - t0:.1f} s contains a gap: "
                             f"{describe_gaps(gaps, t0, derived)}; no fit over missing data: choose a window "
                             "without it (window_start / window_end / window_last)")
    if hi - lo < min_duration:
        raise FitWindowError(f"the window holds {max(hi - lo, 0.0):.1f} s of data "
                             f"({lo - t0:.1f} to {hi - t0:.1f} s after the first IMU sample); "
                             f"min_duration is {min_duration:g} s: wait for more data or widen the window"
                             + (f" [{notes[0]}]" if notes else ""))
    return FitWindow(lo, hi, tuple(notes))
