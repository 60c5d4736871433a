"""What a run tells the rig model: the Cramér–Rao bound of the tensor entries for a simulated run.

The bound is the rig model's own (:func:`~rig_identification.estimation.rig_fit.cramer_rao`: the
inverse Fisher information of every sensor's weighted residual in the fit's band, at the true
parameters, with the fit's nuisance model — mass under the scale's σ, the CG free, each cable's
stiffness and each load cell's gain under their priors, the survey's σ on every anchor and length,
the initial state free), evaluated along a noise-free simulation of the run with each channel at
the lab's noise level.  It is what ``rig-identify inertia`` reaches on a recording of that run
(σ/CRB 1.00–1.2 on the shipped recordings, ``python bench/bench_crb.py --recording``), so
:mod:`~rig_identification.design.planning` predicts the plan's σ with it.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..estimation.rig_fit import cramer_rao
from ..estimation.rig_record import Record, record
from ..estimation.rig_unknowns import Layout, Prior
from ..io.rig import Rig, inertia_tensor
from ..model.cables import DEFAULT_DAMPING_RATIO
from ..model.linear_rig import RigParameters
from ..model.parametrisation import from_tensor
from ..model.simulator import SimResult

#: The noise key (:data:`~rig_identification.model.experiment.REFERENCE_NOISE`'s) of each rig-model
#: channel, by the channel name's prefix.
NOISE_OF_CHANNEL = {"tension": "load_cell", "gyro": "gyro", "accel": "accelerometer", "incl": "inclinometer",
                    "exciter": "exciter"}


def channel_noise(channels: Sequence[str], noise: dict[str, float]) -> np.ndarray:
    """(len(channels),) the white-noise σ of each rig-model channel (``tension:c0``, ``gyro_x``, …)
    from ``noise``, a mapping of :data:`NOISE_OF_CHANNEL`'s keys (N, rad/s, m/s², rad, N).
    Raises ``KeyError`` naming a channel whose noise ``noise`` does not give."""
    out = []
    for c in channels:
        key = next((v for k, v in NOISE_OF_CHANNEL.items() if c.startswith(k)), None)
        if key is None or key not in noise:
            raise KeyError(f"no noise level for channel {c!r} (noise keys: {', '.join(noise)})")
        out.append(float(noise[key]))
    return np.array(out)


def true_parameters(rig: Rig, truth: dict[str, Any]) -> RigParameters:
    """The rig model's parameters of a simulation's truth mapping (truth.yaml's: mass, CG, tensor
    about the CG, ``simulator.cable_stiffness`` and ``cable_damping``; the package simulator's
    defaults — 5 MN/m, ζ :data:`~rig_identification.model.cables.DEFAULT_DAMPING_RATIO` — where
    it gives none) on ``rig``'s geometry."""
    J = from_tensor(inertia_tensor(truth["inertia_about_cg"]))
    sim = truth.get("simulator", {})
    k = np.asarray(sim.get("cable_stiffness", [5e6] * len(rig.cables)), float)
    c = np.asarray(sim.get("cable_damping", 2 * DEFAULT_DAMPING_RATIO * np.sqrt(k * truth["mass"] / len(k))), float)
    return RigParameters.from_rig(rig, J, k, float(np.mean(c / k)), truth["mass"], truth["center_of_gravity"])


def tensor_covariance(sim: SimResult, noise: dict[str, float]) -> np.ndarray:
    """(6, 6) kg²·m⁴ the Cramér–Rao bound of the tensor entries (ixx, ixy, ixz, iyy, iyz, izz about
    the CG) for the run ``sim`` simulated (noise-free), each channel at its level in ``noise``
    (:func:`channel_noise`), under the rig model's nuisance model (module docstring).  Raises
    :class:`~rig_identification.estimation.rig_record.RigFitError` where the run gives the rig
    model nothing to fit (no exciter, under 10 s after the spin-up)."""
    rc = record(sim.sensors, sim.rig)
    return record_covariance(replace(rc, sigma=channel_noise(rc.channels, noise)), sim.rig, sim.truth)


def record_covariance(rc: Record, rig: Rig, truth: dict[str, Any]) -> np.ndarray:
    """(6, 6) kg²·m⁴ the Cramér–Rao bound of the tensor entries for the record ``rc`` (its input
    and its channels' σ) at the true parameters of ``truth`` (:func:`true_parameters`), under the
    rig model's nuisance model (module docstring)."""
    p = true_parameters(rig, truth)
    cov = cramer_rao(rc, rig, Prior.from_rig(rig.with_cg(p.cg)), p)
    inertia = Layout(len(rig.cables)).inertia
    block: np.ndarray = cov[inertia, inertia]
    return block


def tensor_bound(sim: SimResult, noise: dict[str, float]) -> np.ndarray:
    """(6,) kg·m² the Cramér–Rao bound (1 σ) of each tensor entry (:func:`tensor_covariance`)."""
    return np.sqrt(np.diag(tensor_covariance(sim, noise)))


def combined_std(covariances: Sequence[np.ndarray]) -> np.ndarray:
    """(6,) kg·m² the σ of each tensor entry from several runs of the same body, each run's
    information added (the runs' nuisance — initial state, force, stiffness, gains — taken as
    their own: slightly pessimistic where runs share a rig day's)."""
    info = sum(np.linalg.pinv(c, hermitian=True) for c in covariances)
    return np.sqrt(np.diag(np.linalg.pinv(np.asarray(info), hermitian=True)))


__all__ = ["NOISE_OF_CHANNEL", "channel_noise", "true_parameters", "tensor_covariance", "record_covariance",
           "tensor_bound", "combined_std"]
