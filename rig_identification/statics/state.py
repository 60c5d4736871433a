"""A static state of the suspended body: the mean of every sensor stream over a window at rest.

The static experiment (thesis chapter 2, section 2.2) records the body at rest; each stream's
window is tested for stationarity (batch means against the sample-to-sample noise, a χ² test)
and averaged, with the σ of the mean.  A :class:`StaticState` is what
:func:`~rig_identification.statics.estimation.estimate_cg` takes.  :class:`StaticsError`, the
error of the whole static experiment, is defined here, in the package's lowest module.

Frames and units (docs/recording_format.md): sensor frames; SI units (m, kg, N, rad, s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
from scipy.stats import chi2 as _chi2

from ..io.recording import SensorData, TimeSeries
from ..io.rig import DummyMass, Rig

MOTION_P = 1e-4                  # per-channel p-value below which a state is "moving"
#: The stationarity test's batches last about this long, s (5 to 20 batches a window).
BATCH_SECONDS = 1.0
#: The quiet tail averaged where a state's first batches still move: at least this share of its window.
MIN_QUIET_FRACTION = 0.4


class StaticsError(ValueError):
    """Inconsistent static-experiment input (slack cable, ineffective dummy, unreachable
    angles, moving body, contradictory geometry, missing data)."""



# --- stream statistics and static states ------------------------------------------------------

@dataclass(frozen=True)
class StreamStats:
    """Mean of one sensor stream over a window.

    mean, std_of_mean, scatter: (k,) per channel (std_of_mean = scatter / sqrt(n) for a
    stationary stream, the batch-means standard error when motion is accepted).
    n: samples.  motion_p: (k,) p-value of the stationarity test (batch means vs the
    sample-to-sample noise; small = the stream still moves).
    """

    mean: np.ndarray
    std_of_mean: np.ndarray
    scatter: np.ndarray
    n: int
    motion_p: np.ndarray


def _batch_test(x: np.ndarray, K: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stationarity test of samples x (n, k) in K consecutive batches.

    Returns (p-value (k,), noise σ from first differences (k,), batch-means standard error
    of the mean (k,)).  Under white noise Σ n_b (x̄_b - x̄)² / σ² ~ χ²(K - 1).
    """
    n = len(x)
    edges = np.linspace(0, n, K + 1).astype(int)
    bm = np.array([x[a:b].mean(0) for a, b in zip(edges[:-1], edges[1:])])
    nb = np.diff(edges)[:, None]
    mean = x.mean(0)
    sd = np.sqrt(np.mean(np.diff(x, axis=0) ** 2, axis=0) / 2.0) if n > 2 else np.zeros(x.shape[1])
    floor = 1e-9 * (np.abs(mean) + 1.0)
    sd = np.maximum(sd, floor)
    q = np.sum(nb * (bm - mean) ** 2, axis=0) / sd**2
    p = _chi2.sf(q, K - 1)
    se_batch = np.sqrt(np.sum((bm - mean) ** 2, axis=0) / (K * (K - 1)))
    return p, sd, se_batch


def _stats(x: np.ndarray, K: int, accept_motion: bool) -> StreamStats:
    p, sd, se_b = _batch_test(x, K)
    n = len(x)
    scatter = x.std(0, ddof=1) if n > 1 else np.zeros(x.shape[1])
    floor = 1e-9 * (np.abs(x.mean(0)) + 1.0)
    scatter = np.maximum(scatter, floor)
    se = scatter / math.sqrt(n)
    if accept_motion:
        se = np.maximum(se, se_b)
    return StreamStats(x.mean(0), se, scatter, n, p)


@dataclass(frozen=True)
class _Windows:
    """Every stream of a state over one window: ``streams`` the samples of each (``imu``,
    ``load_cell:<name>``, ``inclinometer``, ``exciter``) within it, [``a``, ``b``] s the header
    stamps all of them cover, ``K`` the batches of the stationarity test (5 to 20)."""

    streams: dict[str, TimeSeries]
    a: float
    b: float
    K: int


def _stream_windows(sensors: SensorData, t0: float, t1: float, label: str) -> _Windows:
    """The streams of ``sensors`` within header stamps [t0, t1] s, cut into batches of about
    :data:`BATCH_SECONDS` s.  Raises :class:`StaticsError` for a stream with under 10 samples there
    or streams that do not overlap in time."""
    streams: dict[str, TimeSeries] = {"imu": sensors.imu}
    for name, ts in sensors.load_cells.items():
        streams["load_cell:" + name] = ts
    if sensors.inclinometer is not None:
        streams["inclinometer"] = sensors.inclinometer
    if sensors.exciter is not None:
        streams["exciter"] = sensors.exciter
    win = {}
    for k, ts in streams.items():
        w = ts.window(t0, t1)
        if len(w) < 10:
            raise StaticsError(f"{label}: stream {k} has {len(w)} sample(s) in the window "
                               f"[{t0:.3f}, {t1:.3f}] s; at least 10 are needed")
        win[k] = w
    a = max(w.t[0] for w in win.values())
    b = min(w.t[-1] for w in win.values())
    if b - a <= 0:
        raise StaticsError(f"{label}: the streams do not overlap in time")
    return _Windows(win, a, b, int(np.clip(round((b - a) / BATCH_SECONDS), 5, 20)))


def _stationarity(win: _Windows, ta: float) -> tuple[float, str]:
    """The smallest p-value of the stationarity test (:func:`_batch_test`) over every channel
    of every stream in [ta, b] s, and the channel (``stream[column]``); 0 when a stream has
    fewer than 2 K samples there."""
    worst, what = 1.0, ""
    for k, w in win.streams.items():
        x = w.window(ta, win.b).data
        if len(x) < 2 * win.K:
            return 0.0, f"{k}: too few samples"
        p, _, _ = _batch_test(x, win.K)
        if p.min() < worst:
            worst, what = float(p.min()), f"{k}[{int(np.argmin(p))}]"
    return worst, what


def _first_quiet(win: _Windows) -> float | None:
    """The first batch edge a + j (b - a) / K, j >= 1, from which every stream is at rest (p of
    :func:`_stationarity` at least :data:`MOTION_P`) with at least :data:`MIN_QUIET_FRACTION` of
    the window left; None when there is none."""
    a, b = win.a, win.b
    step = (b - a) / win.K
    j = 1
    while (b - (a + j * step)) >= MIN_QUIET_FRACTION * (b - a) - 1e-9:
        pj, _ = _stationarity(win, a + j * step)
        if pj >= MOTION_P:
            return a + j * step
        j += 1
    return None


def _rest_start(win: _Windows, label: str, allow_motion: bool) -> tuple[float, bool, list[str]]:
    """(start s of the span averaged, moving, warnings) of :meth:`StaticState.from_window`: the
    window's start when it is at rest; else the start of its quiet tail (:func:`_first_quiet`);
    else, with ``allow_motion``, the start and moving.  Raises :class:`StaticsError` when the
    body still moves."""
    a, b = win.a, win.b
    p, what = _stationarity(win, a)
    if not p < MOTION_P:
        return a, False, []
    start = _first_quiet(win)
    if start is not None:
        return start, False, [f"{label}: the body still moved during the first {start - a:.1f} s "
                              f"({what} not stationary); averaged the last {b - start:.1f} s"]
    if allow_motion:
        return a, True, [f"{label}: the body still moves over the whole window ({what} not "
                         f"stationary, p = {p:.1e}); averaged anyway with the batch-means "
                         "uncertainty"]
    raise StaticsError(f"{label}: the body still moves ({what} is not stationary over "
                       f"{b - a:.1f} s, p = {p:.1e}): no state at rest to use; wait until it "
                       "settles and record again")


def _exciter_warnings(exc: StreamStats | None, label: str) -> list[str]:
    """A warning when the exciter's load cells (their :class:`StreamStats`, or None) read a
    mean force at rest, N, beyond 1 N and 5 σ of the mean."""
    if exc is None:
        return []
    f = exc.mean
    if float(np.linalg.norm(f)) > max(1.0, 5 * float(np.linalg.norm(exc.std_of_mean))):
        return [f"{label}: the exciter load cells read a mean force of "
                f"{np.linalg.norm(f):.1f} N at rest; ignored (is the exciter off?)"]
    return []


@dataclass(frozen=True)
class StaticState:
    """One static state of the body: the mean of every sensor stream over a window at rest.

    Attributes (means over the window, sensor frames of docs/recording_format.md):

    * ``cable_names`` (N,) and ``tensions`` (N,) N with ``tensions_std`` (N,) N (std of the
      mean), or ``None`` without load cells;
    * ``elevations`` (2,) rad, ``elevations_std`` (2,) rad: inclinometer x, y elevations
      (thesis's c31, c32 as angles), or ``None``;
    * ``specific_force`` (3,) m/s², ``specific_force_std`` (3,): accelerometer, IMU axes, or ``None``;
    * ``added``: dummy masses fixed on the body in this state (body frame), ``None`` = let
      :func:`estimate_cg` decide (baseline: none; dummy: ``rig.dummy_mass``);
    * ``window`` (t0, t1) header stamps s actually averaged, ``samples`` per stream,
      ``label``, ``warnings`` (e.g. the body still moved at the start and was trimmed),
      ``moving`` (accepted although the stationarity test failed), ``stats``
      (:class:`StreamStats` per stream: ``imu``, ``load_cell:<name>``, ``inclinometer``,
      ``exciter``) and ``exciter_force`` (2,) N (mean exciter reading, ignored by the fit).

    A node captures a state by buffering the live topics into a :class:`SensorData` and
    calling :meth:`from_window`; :func:`estimate_cg` then takes two (or more) states.
    """

    cable_names: tuple[str, ...] | None = None
    tensions: np.ndarray | None = None
    tensions_std: np.ndarray | None = None
    elevations: np.ndarray | None = None
    elevations_std: np.ndarray | None = None
    specific_force: np.ndarray | None = None
    specific_force_std: np.ndarray | None = None
    added: tuple[DummyMass, ...] | None = None
    window: tuple[float, float] = (0.0, 0.0)
    samples: dict = field(default_factory=dict)
    label: str = "state"
    warnings: list[str] = field(default_factory=list)
    moving: bool = False
    stats: dict = field(default_factory=dict)
    exciter_force: np.ndarray | None = None

    @classmethod
    def from_window(cls, sensors: SensorData, t0: float | None = None, t1: float | None = None,
                    label: str = "state", allow_motion: bool = False,
                    added: Sequence[DummyMass] | None = None) -> "StaticState":
        """Average every stream of ``sensors`` over header stamps [t0, t1] s (default: all).

        Stationarity: each channel's window is cut into ~:data:`BATCH_SECONDS` batches (5 to
        20); if their means scatter more than the sample-to-sample noise allows (χ² test,
        p < :data:`MOTION_P` on any channel: the body still swings or drifts), leading batches
        are dropped until the rest is at rest (at least :data:`MIN_QUIET_FRACTION` of the
        window); a warning says so.  If no quiet tail exists: :class:`StaticsError`
        ("the body still moves"), unless ``allow_motion`` (then the batch-means standard
        error is used and a warning is added).  ``added``: the dummy masses fixed in this
        state (body frame), if known here.  Raises :class:`StaticsError` for an empty window.
        """
        t0 = -np.inf if t0 is None else float(t0)
        t1 = np.inf if t1 is None else float(t1)
        win = _stream_windows(sensors, t0, t1, label)
        start, moving, warnings = _rest_start(win, label, allow_motion)
        st = {k: _stats(w.window(start, win.b).data, win.K, moving) for k, w in win.streams.items()}
        exc = st.get("exciter")
        warnings += _exciter_warnings(exc, label)
        names = tuple(sensors.load_cells)
        tens = np.array([st["load_cell:" + n].mean[0] for n in names]) if names else None
        tens_sd = np.array([st["load_cell:" + n].std_of_mean[0] for n in names]) if names else None
        inc = st.get("inclinometer")
        imu = st["imu"]
        return cls(cable_names=names or None, tensions=tens, tensions_std=tens_sd,
                   elevations=None if inc is None else inc.mean,
                   elevations_std=None if inc is None else inc.std_of_mean,
                   specific_force=imu.mean[3:6], specific_force_std=imu.std_of_mean[3:6],
                   added=None if added is None else tuple(added), window=(float(start), float(win.b)),
                   samples={k: v.n for k, v in st.items()}, label=label, warnings=warnings,
                   moving=moving, stats=st, exciter_force=None if exc is None else exc.mean)

    @classmethod
    def from_recording(cls, recording, label: str = "state", **kw) -> "StaticState":
        """:meth:`from_window` over a whole :class:`~rig_identification.io.recording.Recording`."""
        st = cls.from_window(recording.sensors, label=label, **kw)
        return replace(st, warnings=[f"{recording.path}: {w}" for w in recording.warnings] + st.warnings)

    def reading(self, stream: str) -> tuple[np.ndarray, np.ndarray]:
        """(mean, σ of the mean) of the ``inclinometer`` (elevations (2,) rad) or the
        ``accelerometer`` (specific force (3,) m/s², IMU axes).  Raises :class:`StaticsError`
        when this state has none."""
        mean, std = {"inclinometer": (self.elevations, self.elevations_std),
                     "accelerometer": (self.specific_force, self.specific_force_std)}[stream]
        if mean is None or std is None:
            raise StaticsError(f"{self.label}: no {stream} reading")
        return mean, std

    def tensions_for(self, rig: Rig) -> tuple[np.ndarray, np.ndarray] | None:
        """(tensions (N,), std (N,)) in rig.yaml cable order, or None without load cells.

        Raises :class:`StaticsError` if a cable of the rig has no load cell here."""
        if self.tensions is None:
            return None
        if self.cable_names is None or self.tensions_std is None:
            raise StaticsError(f"{self.label}: tensions without their cable names or σ")
        idx = {n: i for i, n in enumerate(self.cable_names)}
        missing = [n for n in rig.cable_names if n not in idx]
        if missing:
            raise StaticsError(f"{self.label}: no load-cell reading for cable(s) {', '.join(missing)}")
        order = [idx[n] for n in rig.cable_names]
        return self.tensions[order], self.tensions_std[order]

