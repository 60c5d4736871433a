"""Fresh white noise at given levels added to a recording's streams (:func:`add_noise`; antithetic
pairs ``s ± m`` with ``sign``), for the benches' Monte Carlo draws.
"""
from __future__ import annotations

import numpy as np

from ..io.recording import SensorData, TimeSeries


def add_noise(sensors: SensorData, noise: dict[str, float], rng: np.random.Generator, sign: float = 1.0) -> SensorData:
    """A copy of ``sensors`` (:class:`~rig_identification.io.recording.SensorData`) with white noise of the σ in
    ``noise`` (keys of :data:`~rig_identification.model.experiment.REFERENCE_NOISE`) added
    (``sign`` = +1) or the same realisation
    subtracted (``sign`` = −1): pass generators in the same state for an antithetic pair.
    Draws in the order IMU (N,6), load cells, exciter, inclinometer."""

    def add(ts: TimeSeries | None, sig: float | list[float]) -> TimeSeries | None:
        if ts is None:
            return None
        z = rng.standard_normal(ts.data.shape)
        return TimeSeries(ts.t, ts.data + sign * np.asarray(sig, float) * z)

    imu = add(sensors.imu, [noise["gyro"]] * 3 + [noise["accelerometer"]] * 3)
    cells = {n: add(sensors.load_cells[n], noise["load_cell"]) for n in sensors.load_cells}
    return SensorData(imu, cells, add(sensors.exciter, noise["exciter"]),  # type: ignore[arg-type]  # add(): None for None only
                      add(sensors.inclinometer, noise["inclinometer"]))
