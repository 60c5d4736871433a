"""The sensors' noise estimated from the data (io.quality.white_sigma) and the noise the benches
add (estimation.uncertainty.add_noise)."""
import numpy as np
import pytest

from rig_identification.estimation.uncertainty import add_noise
from rig_identification.io.quality import white_sigma
from rig_identification.io.recording import SensorData, TimeSeries


def test_white_sigma_ignores_slow_motion_and_steps():
    rng = np.random.default_rng(3)
    fs = 200.0
    t = np.arange(0, 60, 1 / fs)
    x = 5.0 * np.sin(2 * np.pi * 1.2 * t) + 2.0 * np.sin(2 * np.pi * 2.9 * t + 1) + 30.0 * (t > 20)
    sig = 0.01
    est = white_sigma(x + sig * rng.standard_normal(len(t)))
    assert est == pytest.approx(sig, rel=0.03)
    # without noise, the motion alone reads as (almost) nothing
    assert white_sigma(x) < 0.05 * sig


def test_antithetic_noise_cancels_and_has_the_levels_asked():
    """add_noise with sign ±1 from generators in the same state: the two draws cancel exactly
    (an antithetic pair), and each has the σ asked of its stream."""
    t = np.arange(20000) * 0.005
    sensors = SensorData(TimeSeries(t, np.zeros((len(t), 6))), {"c0": TimeSeries(t, np.full(len(t), 100.0))})
    noise = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5, "inclinometer": 0.0002}
    plus = add_noise(sensors, noise, np.random.default_rng(7), 1.0)
    minus = add_noise(sensors, noise, np.random.default_rng(7), -1.0)
    np.testing.assert_allclose(plus.imu.data + minus.imu.data, 0.0, atol=1e-15)
    np.testing.assert_allclose(plus.load_cells["c0"].data + minus.load_cells["c0"].data, 200.0, rtol=1e-15)
    assert np.std(plus.imu.data[:, 0]) == pytest.approx(0.002, rel=0.03)
    assert np.std(plus.imu.data[:, 4]) == pytest.approx(0.01, rel=0.03)
    assert np.std(plus.load_cells["c0"].data) == pytest.approx(0.5, rel=0.03)
