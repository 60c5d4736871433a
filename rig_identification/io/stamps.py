"""A stream's stamps regularised from its rate where they jitter: a sensor stamped on arrival.

An IMU without hardware stamps (USB, serial) is stamped when its message arrives: the samples
are taken at a steady rate, their stamps are late by a varying 0–4 ms.  Taken as they are, a
stamp interval 1.5 times the median reads as a dropped message and a fit refuses the window.
:func:`regular_stamps` fits t_k = c + s n_k by least squares over each run of the stream between
real gaps (longer than :data:`RUN_GAP`), n_k the sample's number on the sensor's clock, and puts
the samples on that line when every stamp lies within half a period of it.  The numbers come
from the clock's period (:func:`clock_period`: where the stamps' phases cluster) and the phases'
mean (:func:`sample_numbers`), so a sample lost inside a run leaves its number out (a gap of one
period) instead of shifting the rest by a whole period; neither single intervals (0–4 ms of
jitter on a 5 ms period makes intervals of 1–9 ms) nor the median interval (a few µs off: a whole
period over a few thousand samples) can number them.  The mean delay stays in the intercept, a constant delay between
streams, which ``diagnose`` looks for (``sensor_delay``).  Stamps in s.
"""
from __future__ import annotations

import numpy as np

#: Stamp intervals within this share of the median interval are steady: the stream is left as it is.
STEADY_SHARE = 0.1
#: Gaps longer than this (s) are real (dropped messages, a paused recording): runs are fitted apart.
RUN_GAP = 0.1
#: Runs shorter than this many samples are left as they are (too few to fit a rate).
MIN_RUN = 20
#: The clock's period is searched first over this many of a run's stamps, within this share of
#: the median interval either side (:func:`clock_period`): on 0.8 periods of jitter the median
#: interval of a few hundred stamps is a few percent off, and the phases of fewer than about 1000
#: stamps cluster too weakly to tell the clock from noise.
FIRST_SPAN = 1000
SEARCH_SHARE = 0.03
#: The stamps a search level uses at most (evenly spaced through the span it searches).
MOST_STAMPS = 2000
#: Rayleigh's statistic m R² (R the stamps' phase concentration on the clock found, m the stamps)
#: below which no clock is taken: the chance that phases with no clock cluster as well is e^-10.
RAYLEIGH_MIN = 10.0


def phase_concentration(x: np.ndarray, periods: np.ndarray) -> np.ndarray:
    """(k,) the mean resultant length |mean exp(2πi x / P)| of the stamps ``x`` (m,) s on each
    period P of ``periods`` (k,) s: 1 where every stamp falls at the same phase of the clock, about
    1/√m where the stamps keep no clock of that period (Mardia & Jupp, *Directional Statistics*, §3.4)."""
    out: np.ndarray = np.abs(np.exp(2j * np.pi * np.outer(1.0 / periods, x)).mean(axis=1))
    return out


def clock_period(t: np.ndarray, near: float) -> float:
    """The period s of the clock the stamps ``t`` (one run, s, increasing) were taken on: where
    their phases cluster most (:func:`phase_concentration`; epoch folding — the peak stands however
    the stamps jitter within a period and whichever samples were lost), searched within
    :data:`SEARCH_SHARE` of ``near`` (the median interval) over the first :data:`FIRST_SPAN`
    stamps, then over spans four times as long, each within the last peak's width, on a grid of
    an eighth of the span's peak width P²/span."""
    period = near
    span = min(len(t), FIRST_SPAN)
    half = SEARCH_SHARE * near
    while True:
        x = (t[:span] - t[0])[::max(1, span // MOST_STAMPS)]
        width = period * period / x[-1]
        grid = period + np.arange(-half, half + width / 8, width / 8)
        period = float(grid[np.argmax(phase_concentration(x, grid))])
        if span == len(t):
            return period
        half, span = width, min(len(t), 4 * span)


def sample_numbers(t: np.ndarray, near: float) -> tuple[np.ndarray, float, float] | None:
    """The sample numbers n (len(t),) of the stamps ``t`` (s, increasing, one run) on their clock
    (:func:`clock_period`, ``near`` the median interval s), and the line t ≈ c + s n fitted to them
    by least squares: (n, c, s).  None where the stamps keep no clock (Rayleigh's statistic below
    :data:`RAYLEIGH_MIN`), a stamp lies half a period or more off the line, or two stamps take one
    number.  The numbers: each stamp's offset from the phases' circular mean in periods, rounded,
    then again from the line fitted to them."""
    period = clock_period(t, near)
    z = np.exp(2j * np.pi * (t - t[0]) / period).mean()
    if len(t) * abs(z) ** 2 < RAYLEIGH_MIN:
        return None
    c, s = t[0] + period * float(np.angle(z)) / (2 * np.pi), period
    for _ in range(2):
        n = np.round((t - c) / s)
        s, c = np.polyfit(n, t, 1)
    if np.any(np.diff(n) < 1) or np.max(np.abs(t - (c + s * n))) >= 0.5 * s:
        return None
    return n, float(c), float(s)


def regular_stamps(t: np.ndarray, topic: str) -> tuple[np.ndarray, str | None]:
    """The stamps ``t`` (n,) s, increasing, regularised where they jitter (module docstring), and
    a warning naming ``topic`` when they were, with the samples lost inside the runs (None when
    they were steady or could not be: a run whose stamps stray half a period from any steady
    rate keeps its stamps, and the gap rule then speaks for it)."""
    if len(t) < MIN_RUN:
        return t, None
    dt = np.diff(t)
    med = float(np.median(dt))
    if not med > 0 or np.all(np.abs(dt - med) <= STEADY_SHARE * med):
        return t, None
    out = t.copy()
    edges = np.r_[0, np.nonzero(dt > max(RUN_GAP, 3 * med))[0] + 1, len(t)]
    jitter, slopes, fixed, kept, lost = [], [], 0, 0, 0
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a < MIN_RUN:
            kept += b - a
            continue
        if np.all(np.abs(dt[a:b - 1] - med) <= STEADY_SHARE * med):
            continue                                    # this run is steady
        line = sample_numbers(t[a:b], med)
        if line is None:
            kept += b - a
            continue
        k, icept, slope = line
        out[a:b] = icept + slope * k
        jitter.append(t[a:b] - out[a:b])
        slopes.append(slope)
        fixed += b - a
        lost += int(k[-1] - k[0]) + 1 - (b - a)
    if not fixed:
        return t, None
    r = np.concatenate(jitter)
    note = (f"topic {topic}: stamps jitter by {1e3 * r.std():.2f} ms RMS (up to {1e3 * np.ptp(r):.1f} ms: stamped on "
            f"arrival?); {fixed} of {len(t)} samples put on the stream's own rate, {1 / np.mean(slopes):.4g} Hz")
    if lost:
        note += f"; {lost} sample(s) lost inside the runs, each left as a gap of one period"
    if kept:
        note += f"; {kept} left as stamped (no steady rate within half a period, or too short a run)"
    return out, note
