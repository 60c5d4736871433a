"""A stream's stamps regularised from its rate where they jitter: a sensor stamped on arrival.

An IMU without hardware stamps (USB, serial) is stamped when its message arrives: the samples
are taken at a steady rate, their stamps are late by a varying 0–4 ms.  Taken as they are, a
stamp interval 1.5 times the median reads as a dropped message and a fit refuses the window.
:func:`regular_stamps` fits t_k = c + s k by least squares over each run of the stream between
real gaps (longer than :data:`~rig_identification.io.bad_spans.SHORT_GAP`'s 0.1 s) and puts
the samples on that line when every stamp lies within half a period of it (no sample lost
inside the run: a lost one would shift the rest by a whole period).  The mean delay stays in
the intercept, a constant delay between streams, which ``diagnose`` looks for (``sensor_delay``).
Stamps in s.
"""
from __future__ import annotations

import numpy as np

#: Stamp intervals within this share of the median interval are steady: the stream is left as it is.
STEADY_SHARE = 0.1
#: Gaps longer than this (s) are real (dropped messages, a paused recording): runs are fitted apart.
RUN_GAP = 0.1
#: Runs shorter than this many samples are left as they are (too few to fit a rate).
MIN_RUN = 20


def regular_stamps(t: np.ndarray, topic: str) -> tuple[np.ndarray, str | None]:
    """The stamps ``t`` (n,) s, increasing, regularised where they jitter (module docstring), and
    a warning naming ``topic`` when they were (None when they were steady or could not be: a
    run with a lost sample inside keeps its stamps, and the gap rule then speaks for it)."""
    if len(t) < MIN_RUN:
        return t, None
    dt = np.diff(t)
    med = float(np.median(dt))
    if not med > 0 or np.all(np.abs(dt - med) <= STEADY_SHARE * med):
        return t, None
    out = t.copy()
    edges = np.r_[0, np.nonzero(dt > max(RUN_GAP, 3 * med))[0] + 1, len(t)]
    jitter, slopes, fixed, kept = [], [], 0, 0
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a < MIN_RUN:
            kept += b - a
            continue
        if np.all(np.abs(dt[a:b - 1] - med) <= STEADY_SHARE * med):
            continue                                    # this run is steady
        k = np.arange(b - a, dtype=float)
        slope, icept = np.polyfit(k, t[a:b], 1)
        r = t[a:b] - (icept + slope * k)
        if np.max(np.abs(r)) >= 0.5 * slope:
            kept += b - a
            continue
        out[a:b] = icept + slope * k
        jitter.append(r)
        slopes.append(slope)
        fixed += b - a
    if not fixed:
        return t, None
    r = np.concatenate(jitter)
    note = (f"topic {topic}: stamps jitter by {1e3 * r.std():.2f} ms RMS (up to {1e3 * np.ptp(r):.1f} ms: stamped on "
            f"arrival?); {fixed} of {len(t)} samples put on the stream's own rate, {1 / np.mean(slopes):.4g} Hz")
    if kept:
        note += f"; {kept} left as stamped (a lost sample inside their run, or too short a run)"
    return out, note
