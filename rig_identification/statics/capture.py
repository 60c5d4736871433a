"""Live capture of the static centre-of-gravity experiment (ROS-free core of the node services).

A lab engineer hangs the body, waits for it to settle, captures the *baseline* state,
fixes the dummy mass, waits again, captures the *dummy* state, and asks for the estimate.
:class:`CgSession` keeps the last ``seconds`` of every raw stream (IMU, load cells, exciter,
inclinometer, by header stamp) and turns them into :class:`~.statics.StaticState` on demand
(the same averaging and stationarity test as ``rig-identify cg`` on recordings), then calls
:func:`~.statics.estimate_cg`.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from ..io.recording import SensorData, TimeSeries
from ..io.rig import DummyMass, Rig
from . import CgResult, StaticsError, StaticState, estimate_cg


class _Buffer:
    """(t, values...) rows of one stream, trimmed to the last ``seconds``."""

    def __init__(self, seconds: float):
        self.seconds = seconds
        self.rows: deque = deque()

    def add(self, t: float, *values: float) -> None:
        if self.rows and t <= self.rows[-1][0]:
            raise ValueError(f"stamp {t:.6f} s not after the previous one")
        self.rows.append((t, *values))
        while self.rows and self.rows[0][0] < t - self.seconds:
            self.rows.popleft()

    def series(self) -> TimeSeries | None:
        if len(self.rows) < 2:
            return None
        a = np.array(self.rows, float)
        return TimeSeries(a[:, 0], a[:, 1:])


class CgSession:
    """Capture two static states from live samples and estimate the CG.

    seconds: averaging window (the last ``seconds`` before the capture).
    dummy: the dummy mass to assume for the dummy state (default: rig.yaml's ``dummy_mass``).
    Errors: :class:`~.statics.StaticsError` with a message for the lab engineer.
    """

    def __init__(self, rig: Rig, seconds: float = 10.0, dummy: DummyMass | None = None):
        self.rig = rig
        self.seconds = seconds
        self.dummy = dummy if dummy is not None else rig.dummy_mass
        self._imu = _Buffer(seconds)
        self._cells = {n: _Buffer(seconds) for n in rig.cable_names}
        self._exc = _Buffer(seconds)
        self._incl = _Buffer(seconds)
        self.baseline: StaticState | None = None
        self.dummy_state: StaticState | None = None

    # --- samples ------------------------------------------------------------------
    def add_imu(self, t: float, gyro, accel) -> None:
        self._imu.add(t, *np.asarray(gyro, float), *np.asarray(accel, float))

    def add_tension(self, name: str, t: float, tension: float) -> None:
        self._cells[name].add(t, float(tension))

    def add_exciter(self, t: float, fx: float, fy: float) -> None:
        self._exc.add(t, float(fx), float(fy))

    def add_inclinometer(self, t: float, angles) -> None:
        a = np.asarray(angles, float)
        self._incl.add(t, a[0], a[1])

    # --- capture and estimate ------------------------------------------------------
    def sensor_data(self) -> SensorData:
        imu = self._imu.series()
        if imu is None:
            raise StaticsError("no IMU samples buffered yet: is /rig/imu publishing?")
        cells = {}
        for n, b in self._cells.items():
            s = b.series()
            if s is None:
                raise StaticsError(f"no samples of /rig/load_cells/{n} buffered yet")
            cells[n] = s
        return SensorData(imu, cells, self._exc.series(), self._incl.series())

    def capture(self, which: str, data: SensorData | None = None) -> StaticState:
        """Capture the ``"baseline"`` or ``"dummy"`` state from the buffered window (or from
        ``data``, a :meth:`sensor_data` snapshot taken earlier, e.g. under a node's lock)."""
        if which not in ("baseline", "dummy"):
            raise ValueError(f"unknown state {which!r} (baseline or dummy)")
        data = self.sensor_data() if data is None else data
        span = data.imu.t[-1] - data.imu.t[0]
        if span < 0.5 * self.seconds:
            raise StaticsError(f"only {span:.1f} s of data buffered; wait {self.seconds:.0f} s at rest before "
                               "capturing")
        added = None
        if which == "dummy":
            if self.dummy is None:
                raise StaticsError("no dummy mass: give rig.yaml a dummy_mass (mass, position) or set the "
                                   "node's dummy_mass/dummy_position parameters")
            added = [self.dummy]
        state = StaticState.from_window(data, label=which, added=added)
        if which == "baseline":
            self.baseline = state
        else:
            self.dummy_state = state
        return state

    def estimate(self) -> CgResult:
        if self.baseline is None or self.dummy_state is None:
            missing = [n for n, s in (("baseline", self.baseline), ("dummy", self.dummy_state)) if s is None]
            raise StaticsError(f"capture the {' and '.join(missing)} state(s) first")
        return estimate_cg(self.rig, self.baseline, self.dummy_state)
