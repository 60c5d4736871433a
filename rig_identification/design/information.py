"""What a run tells the rig model: the Fisher information of the body's unknowns and the Cramér–Rao
bound of the tensor entries for a simulated run, alone or with other runs of the same body.

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
from dataclasses import dataclass, replace
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

#: The body's unknowns at the head of the rig model's vector: the tensor's six entries (kg·m²,
#: :data:`~rig_identification.io.verdict.KEYS` order), the CG (3, body m), the mass (kg).
BODY = 10

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


def nominal_parameters(rig: Rig, inertia: np.ndarray, stiffness: np.ndarray, mass: float) -> RigParameters:
    """The rig model's parameters of a nominal body on ``rig``'s geometry (CG rig.yaml's): the tensor
    ``inertia`` (3, 3) kg·m² about the CG, cable ``stiffness`` (N,) N/m, ``mass`` kg, the cables'
    damping time of the package simulator's damping ratio
    (:data:`~rig_identification.model.cables.DEFAULT_DAMPING_RATIO`: c_i = 2 ζ √(k_i m / N), τ = mean c_i / k_i).
    Raises :class:`~rig_identification.io.rig.RigError` without a CG, ValueError without an exciter."""
    k = np.asarray(stiffness, float)
    tau = float(np.mean(2 * DEFAULT_DAMPING_RATIO * np.sqrt(mass / (len(k) * k))))
    return RigParameters.from_rig(rig, from_tensor(inertia), k, tau, mass, rig.require_cg())


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


def _noisy_record(sim: SimResult, noise: dict[str, float]) -> Record:
    """The record of the run ``sim`` (noise-free) with each channel's σ its level in ``noise``."""
    rc = record(sim.sensors, sim.rig)
    return replace(rc, sigma=channel_noise(rc.channels, noise))


def tensor_covariance(sim: SimResult, noise: dict[str, float]) -> np.ndarray:
    """(6, 6) kg²·m⁴ the Cramér–Rao bound of the tensor entries (ixx, ixy, ixz, iyy, iyz, izz about
    the CG) for the run ``sim`` simulated (noise-free), each channel at its level in ``noise``
    (:func:`channel_noise`), under the rig model's nuisance model (module docstring).  Raises
    :class:`~rig_identification.estimation.rig_record.RigFitError` where the run gives the rig
    model nothing to fit (no exciter, under 10 s after the spin-up)."""
    return record_covariance(_noisy_record(sim, noise), sim.rig, sim.truth)


def body_covariance(rc: Record, rig: Rig, truth: dict[str, Any]) -> np.ndarray:
    """(10, 10) the Cramér–Rao bound of the body's unknowns (:data:`BODY`: tensor kg·m², CG m, mass
    kg) for the record ``rc`` (its input and its channels' σ) at the true parameters of ``truth``
    (:func:`true_parameters`), under the rig model's nuisance model (module docstring), the scale's
    prior on the mass included."""
    p = true_parameters(rig, truth)
    cov: np.ndarray = cramer_rao(rc, rig, Prior.from_rig(rig.with_cg(p.cg)), p)[:BODY, :BODY]
    return cov


def record_covariance(rc: Record, rig: Rig, truth: dict[str, Any]) -> np.ndarray:
    """(6, 6) kg²·m⁴ the Cramér–Rao bound of the tensor entries for the record ``rc``
    (:func:`body_covariance`'s tensor block)."""
    inertia = Layout(len(rig.cables)).inertia
    block: np.ndarray = body_covariance(rc, rig, truth)[inertia, inertia]
    return block


def tensor_bound(sim: SimResult, noise: dict[str, float]) -> np.ndarray:
    """(6,) kg·m² the Cramér–Rao bound (1 σ) of each tensor entry (:func:`tensor_covariance`)."""
    return np.sqrt(np.diag(tensor_covariance(sim, noise)))


@dataclass(frozen=True)
class RunInformation:
    """What one run tells the rig model about the body: ``body`` (10, 10) the Fisher information of the
    body's unknowns (:data:`BODY`: tensor kg·m², CG m, mass kg), the run's own nuisance profiled out and
    no prior on the body (the scale's and the static test's count once, :func:`combined`); ``seconds``
    the fitted span it holds."""

    body: np.ndarray
    seconds: float

    def scaled(self, seconds: float) -> "RunInformation":
        """The same run fitted over ``seconds``: the information grows with the span (steady motion)."""
        return RunInformation(self.body * (seconds / self.seconds), seconds)


def body_prior(rig: Rig) -> np.ndarray:
    """(10, 10) the information of the body's priors in the rig model
    (:class:`~rig_identification.estimation.rig_unknowns.Prior` of ``rig``: the scale's σ on the mass,
    the CG free)."""
    prior = Prior.from_rig(rig)
    info = np.zeros((BODY, BODY))
    info[6:9, 6:9] = np.diag(np.where(np.isfinite(prior.cg_std), 1.0 / prior.cg_std ** 2, 0.0))
    info[9, 9] = 1.0 / prior.mass_std ** 2
    return info


def run_information(sim: SimResult, noise: dict[str, float]) -> RunInformation:
    """The :class:`RunInformation` of the run ``sim`` simulated (noise-free), each channel at its level
    in ``noise``, from the rig model's Cramér–Rao bound (:func:`body_covariance`'s, every nuisance of
    the fit: the survey, the force's correction, the segments' states).  Raises
    :class:`~rig_identification.estimation.rig_record.RigFitError` as :func:`tensor_covariance`."""
    rc = _noisy_record(sim, noise)
    info = np.linalg.inv(body_covariance(rc, sim.rig, sim.truth)) - body_prior(sim.rig)
    return RunInformation(0.5 * (info + info.T), float((len(rc.y) - rc.start) * rc.dt))


#: Condition number beyond which the runs' information leaves some combination of the body's
#: unknowns undetermined (:func:`combined` gives σ inf).
SINGULAR = 1e13


def combined(runs: Sequence[RunInformation], prior: np.ndarray) -> np.ndarray:
    """(10, 10) the covariance of the body's unknowns from the runs together (the joint fit of
    several recordings: their information added, the body's ``prior`` (:func:`body_prior`) once).
    Rows and columns of an undetermined combination are inf."""
    info = sum((r.body for r in runs), np.zeros((BODY, BODY))) + prior
    d = 1.0 / np.sqrt(np.maximum(np.diag(info), 1e-300))
    scaled = info * np.outer(d, d)
    if not np.all(np.isfinite(scaled)) or np.linalg.cond(scaled) > SINGULAR:
        return np.full((BODY, BODY), np.inf)
    cov: np.ndarray = np.linalg.inv(scaled) * np.outer(d, d)
    return cov


def tensor_std(runs: Sequence[RunInformation], prior: np.ndarray) -> np.ndarray:
    """(6,) kg·m² each tensor entry's σ (:data:`~rig_identification.io.verdict.KEYS` order) from the runs
    together (:func:`combined`)."""
    return np.sqrt(np.abs(np.diag(combined(runs, prior))[:6]))


__all__ = ["BODY", "NOISE_OF_CHANNEL", "SINGULAR", "RunInformation", "body_covariance", "body_prior", "channel_noise",
           "combined", "nominal_parameters", "record_covariance", "run_information",
           "tensor_bound", "tensor_covariance", "tensor_std", "true_parameters"]
