"""Synthetic data shared by several test modules: a free rigid body driven by a known moment
(exact Euler dynamics) on a simple 4-cable rig, and a simulated static baseline and dummy pair
on a random rig of N cables."""
import numpy as np
from scipy.integrate import solve_ivp

from rig_identification.design.scenarios import random_experiment
from rig_identification.io.rig import rig_from_dict
from rig_identification.model.experiment import experiment_from_dict
from rig_identification.model.simulator import simulate
from rig_identification.statics import StaticState

RIG = rig_from_dict({"gravity": 9.80665, "cables": [
    {"name": f"c{i}", "ceiling_anchor": [x, y, 0.0], "body_anchor": [x / 2, y / 2, 1.0], "length": 2.0}
    for i, (x, y) in enumerate([(-2, -2), (2, -2), (-2, 2), (2, 2)])],
    "body": {"mass": 1000.0, "center_of_gravity": [0.0, 0.0, 0.0]}, "imu": {"position": [0, 0, 0]}})
J_TRUE = np.array([[900.0, -15.0, 40.0], [-15.0, 2500.0, 25.0], [40.0, 25.0, 2800.0]])


def euler_data(noise=0.0, seed=0, T=120.0, fs=200.0):
    """Free rigid body driven by a known moment: J w' + w x Jw = M (exact ODE solution)."""
    t = np.arange(0, T, 1 / fs)
    f = np.array([0.9, 1.3, 1.7])

    def moment(tt):
        return 300 * np.array([np.sin(2 * np.pi * f[0] * tt), np.cos(2 * np.pi * f[1] * tt + 0.3),
                               np.sin(2 * np.pi * f[2] * tt + 1.0)])

    Jinv = np.linalg.inv(J_TRUE)
    sol = solve_ivp(lambda tt, w: Jinv @ (moment(tt) - np.cross(w, J_TRUE @ w)), (0, T), [0.05, -0.02, 0.03],
                    t_eval=t, rtol=1e-11, atol=1e-13, method="DOP853")
    w = sol.y.T
    rng = np.random.default_rng(seed)
    return t, w + noise * rng.standard_normal(w.shape), moment(t).T


def static_pair(seed: int, cables: int, layout: str = "wide"):
    """(rig, baseline StaticState, dummy StaticState, true CG): a 50 kg dummy 0.3 m below the
    first body anchor (a corner of the carrying frame's top); ``layout`` as
    scenarios.random_experiment's."""
    d = random_experiment(seed, cables, layout, duration=10.0)
    b = np.array([c["body_anchor"] for c in d["rig"]["cables"]])
    d["rig"]["dummy_mass"] = {"mass": 50.0, "position": (b[0] + [0.0, 0.0, -0.3]).tolist()}
    states = []
    for kind in ("baseline", "dummy"):
        d["static"] = {"kind": kind, "duration": 10.0}
        sim = simulate(experiment_from_dict(d, d["name"]))
        states.append(StaticState.from_window(sim.sensors, label=kind))
    return sim.rig, states[0], states[1], np.array(d["rig"]["body"]["center_of_gravity"], float)
