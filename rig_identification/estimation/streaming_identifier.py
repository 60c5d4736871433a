"""The streaming identifier: gyro and generalized wrench samples buffered as they arrive, a window
fitted on request (:class:`InertiaIdentifier`).
"""
from __future__ import annotations

import numpy as np

from ..io.rig import Rig
from .identification import IdentificationError, identify_inertia
from .inertia_result import InertiaResult


class InertiaIdentifier:
    """Streaming buffer for the identifier node: gyro and generalized wrench samples.

    ``identify(start, end, last)`` fits over a window (absolute stamps in s, or the last
    ``last`` seconds) with :func:`~rig_identification.estimation.identification.identify_inertia`.  The wrench samples carry the pose
    stamps, i.e. the IMU stamps; the gyro is interpolated to them.
    """

    def __init__(self, rig: Rig, max_seconds: float = 900.0, **fit_params):
        self.rig = rig
        rig.require_cg()
        self.fit_params = fit_params
        self.max_seconds = max_seconds
        self._imu_t: list[float] = []
        self._gyro: list[np.ndarray] = []
        self._w_t: list[float] = []
        self._torque: list[np.ndarray] = []
        self._imu_to_body = rig.imu.rotation

    def add_imu(self, t: float, gyro) -> None:
        if self._imu_t and t <= self._imu_t[-1]:
            raise ValueError(f"IMU stamp {t:.6f} s not after the previous one")
        self._imu_t.append(float(t))
        self._gyro.append(np.asarray(gyro, float))
        self._trim(self._imu_t, self._gyro)

    def add_wrench(self, w) -> None:
        if self._w_t and w.t <= self._w_t[-1]:
            raise ValueError(f"wrench stamp {w.t:.6f} s not after the previous one")
        self._w_t.append(float(w.t))
        self._torque.append(np.asarray(w.torque, float))
        self._trim(self._w_t, self._torque)

    def _trim(self, ts: list, vals: list) -> None:
        if len(ts) > 1000 and ts[-1] - ts[0] > self.max_seconds * 1.1:
            cut = int(np.searchsorted(ts, ts[-1] - self.max_seconds))
            del ts[:cut], vals[:cut]

    @property
    def span(self) -> tuple[float, float] | None:
        if not self._w_t:
            return None
        return self._w_t[0], self._w_t[-1]

    def identify(self, start: float | None = None, end: float | None = None,
                 last: float | None = None) -> InertiaResult:
        if len(self._w_t) < 10 or len(self._imu_t) < 10:
            raise IdentificationError("identifier: no data buffered yet (is the preprocessor running?)")
        tw = np.array(self._w_t)
        lo = tw[0] if start is None else start
        hi = tw[-1] if end is None else end
        if last is not None:
            lo = max(lo, hi - last)
        m = (tw >= lo) & (tw <= hi)
        ti = np.array(self._imu_t)
        m &= (tw >= ti[0]) & (tw <= ti[-1])
        if m.sum() < 10:
            raise IdentificationError(f"identifier: no samples in the window [{lo:.3f}, {hi:.3f}] s")
        g = np.array(self._gyro)
        gyro = np.column_stack([np.interp(tw[m], ti, g[:, k]) for k in range(3)])
        return identify_inertia(self.rig, tw[m], self._imu_to_body.apply(gyro), np.array(self._torque)[m],
                                **self.fit_params)
