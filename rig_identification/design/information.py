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
from scipy.spatial.transform import Rotation

from ..estimation.rig_fit import cramer_rao
from ..estimation.rig_record import Record, Streams, channel_names, on_model_grid, record
from ..estimation.rig_unknowns import Layout, Prior
from ..io.rig import Mount, Rig, inertia_tensor
from ..model.cables import DEFAULT_DAMPING_RATIO
from ..model.excitation import RotatingForce
from ..model.linear_rig import RigParameters, linearise, natural_frequencies, rest_pose
from ..model.parametrisation import from_tensor
from ..model.rig_ode import drive, rest_state, substeps_for, trajectory
from ..model.simulator import SimResult
from .run import Body, Run

#: The body's unknowns at the head of the rig model's vector: the tensor's six entries (kg·m²,
#: :data:`~rig_identification.io.verdict.KEYS` order), the CG (3, body m), the mass (kg).
BODY = 10

#: The noise key (:data:`~rig_identification.model.experiment.REFERENCE_NOISE`'s) of each rig-model
#: channel, by the channel name's prefix.
NOISE_OF_CHANNEL = {"tension": "load_cell", "gyro": "gyro", "accel": "accelerometer", "incl": "inclinometer",
                    "exciter": "exciter"}
#: The stream (:data:`~rig_identification.model.experiment.REFERENCE_RATES`' key) of each rig-model
#: channel, by the channel name's prefix.
RATE_OF_CHANNEL = {"tension": "load_cells", "gyro": "imu", "accel": "imu", "incl": "inclinometer",
                   "exciter": "exciter"}


def _per_channel(channels: Sequence[str], table: dict[str, str], values: dict[str, float], what: str) -> np.ndarray:
    out = []
    for c in channels:
        key = next((v for k, v in table.items() if c.startswith(k)), None)
        if key is None or key not in values:
            raise KeyError(f"no {what} for channel {c!r} (keys: {', '.join(values)})")
        out.append(float(values[key]))
    return np.array(out)


def channel_noise(channels: Sequence[str], noise: dict[str, float]) -> np.ndarray:
    """(len(channels),) the white-noise σ of each rig-model channel (``tension:c0``, ``gyro_x``, …)
    from ``noise``, a mapping of :data:`NOISE_OF_CHANNEL`'s keys (N, rad/s, m/s², rad, N).
    Raises ``KeyError`` naming a channel whose noise ``noise`` does not give."""
    return _per_channel(channels, NOISE_OF_CHANNEL, noise, "noise level")


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
    return record_covariance(_noisy_record(sim, noise), sim.rig, true_parameters(sim.rig, sim.truth))


def body_covariance(rc: Record, rig: Rig, p: RigParameters) -> np.ndarray:
    """(10, 10) the Cramér–Rao bound of the body's unknowns (:data:`BODY`: tensor kg·m², CG m, mass
    kg) for the record ``rc`` (its input and its channels' σ) of ``rig`` at the true parameters ``p``,
    under the rig model's nuisance model (module docstring), the scale's prior on the mass included."""
    cov: np.ndarray = cramer_rao(rc, rig, Prior.from_rig(rig.with_cg(p.cg)), p)[:BODY, :BODY]
    return cov


def record_covariance(rc: Record, rig: Rig, p: RigParameters) -> np.ndarray:
    """(6, 6) kg²·m⁴ the Cramér–Rao bound of the tensor entries for the record ``rc``
    (:func:`body_covariance`'s tensor block)."""
    inertia = Layout(len(rig.cables)).inertia
    block: np.ndarray = body_covariance(rc, rig, p)[inertia, inertia]
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


@dataclass(frozen=True)
class SimulatedRun:
    """A planned run as the rig model runs it, noise-free (:func:`simulate_run`).

    record: what the fit would be given (:func:`~rig_identification.estimation.rig_record.on_model_grid`),
    each channel's σ the lab's noise level; rig: the body's rig with the run's exciter mount;
    parameters: the nominal body's (:func:`nominal_parameters`); peak_rotation_deg: the body's largest
    rotation from rest, deg; min_tension_ratio: the lowest tension over its static value (spin-up
    and beats included); growing: the swing's peak over its last third exceeds 1.15× the middle
    third's (a parametric resonance)."""

    record: Record
    rig: Rig
    parameters: RigParameters
    peak_rotation_deg: float
    min_tension_ratio: float
    growing: bool


def simulate_run(body: Body, run: Run) -> SimulatedRun:
    """The run ``run`` of ``body`` (its nominal tensor, mass, CG and cable stiffness) simulated from
    rest by the rig model's own integrator (:func:`~rig_identification.model.rig_ode.trajectory`:
    the exact equations with spring–damper cables, ζ
    :data:`~rig_identification.model.cables.DEFAULT_DAMPING_RATIO`), driven by the spinning-up
    rotating force (:class:`~rig_identification.model.excitation.RotatingForce`, ``spin_up``) sampled
    at the fastest of ``body.rates``, each channel's stream at its own rate and noise
    (:data:`RATE_OF_CHANNEL`, :data:`NOISE_OF_CHANNEL`).  Raises
    :class:`~rig_identification.model.rigid_body.SimulationError` (no taut rest pose),
    :class:`~rig_identification.estimation.rig_record.RigFitError` (a run under 10 s after the spin-up),
    ``KeyError`` (a stream's rate or noise missing from ``body``)."""
    max_force = None if body.rig.exciter is None else body.rig.exciter.max_force
    rig = replace(body.rig, exciter=Mount(np.asarray(run.position, float), np.asarray(run.exciter_rpy, float),
                                          max_force))
    p = nominal_parameters(rig, body.inertia, body.stiffness, body.mass)
    channels = channel_names(rig)
    rates = _per_channel(channels, RATE_OF_CHANNEL, body.rates, "rate")
    dt = 1.0 / round(max(float(rates.max()), float(body.rates["exciter"])), 6)
    t = dt * np.arange(int(np.floor(run.duration / dt + 1e-6)) + 1)
    spin = RotatingForce(run.amplitude, run.frequency, run.ramp_time, 0.0, run.direction, ramp_shape="spin_up")
    force = np.array([spin.force(x)[:2] for x in t])
    rest = rest_pose(p)
    substeps = substeps_for(2 * np.pi * natural_frequencies(linearise(p, rest)).max(), dt)
    out, states = trajectory(p, rest_state(p, rest), drive(force, dt, substeps))
    turned = Rotation.from_quat(states[:, [4, 5, 6, 3]])
    ang = np.linalg.norm((turned * turned[0].inv()).as_rotvec(), axis=1)
    n = len(ang)
    tension = out[:, :len(rig.cables)]
    rc = on_model_grid(Streams(0.0, dt, out, channel_noise(channels, body.noise), rates, force,
                               float(body.noise["exciter"]), float(body.rates["exciter"])), rig)
    return SimulatedRun(rc, rig, p, float(np.degrees(ang.max())), float(np.min(tension / tension[0][None, :])),
                        bool(np.max(ang[2 * n // 3:]) > 1.15 * np.max(ang[n // 3: 2 * n // 3])))


def run_information(run: SimulatedRun) -> RunInformation:
    """The :class:`RunInformation` of the simulated ``run`` from the rig model's Cramér–Rao bound
    (:func:`body_covariance`'s, every nuisance of the fit: the survey, the force's correction, the
    segments' states).  Raises ``numpy.linalg.LinAlgError`` where the bound is singular."""
    rc = run.record
    info = np.linalg.inv(body_covariance(rc, run.rig, run.parameters)) - body_prior(run.rig)
    return RunInformation(0.5 * (info + info.T), float((len(rc.y) - rc.start) * rc.dt))


#: The largest variance, in units of its own information (the information scaled to a unit diagonal),
#: beyond which the runs leave some combination of the body's unknowns undetermined
#: (:func:`covariances` gives σ inf): the scaled information's smallest eigenvalue is then below
#: ~10/SINGULAR.
SINGULAR = 1e13


def covariances(info: np.ndarray) -> np.ndarray:
    """(P, 10, 10) the covariance of the body's unknowns for each of P information matrices ``info``
    (P, 10, 10) (:data:`BODY` order): the inverse, by the Cholesky factor of the information scaled to
    a unit diagonal.  Inf where the scaled information is not positive definite or leaves a variance
    over :data:`SINGULAR` (some combination undetermined)."""
    d = 1.0 / np.sqrt(np.maximum(np.einsum("pkk->pk", info), 1e-300))
    scaled = info * d[:, :, None] * d[:, None, :]
    ok = np.all(np.isfinite(scaled), axis=(1, 2))
    cov = np.full(info.shape, np.inf)
    if not np.any(ok):
        return cov
    try:
        np.linalg.cholesky(scaled[ok])
    except np.linalg.LinAlgError:     # some are not positive definite: their smallest eigenvalue says which
        ok[ok] = np.linalg.eigvalsh(scaled[ok])[:, 0] > 0
    idx = np.flatnonzero(ok)
    inv = np.linalg.inv(scaled[idx])
    held = np.max(np.einsum("pkk->pk", inv), axis=1) < SINGULAR
    idx = idx[held]
    cov[idx] = inv[held] * d[idx, :, None] * d[idx, None, :]
    return cov


def combined(runs: Sequence[RunInformation], prior: np.ndarray) -> np.ndarray:
    """(10, 10) the covariance of the body's unknowns from the runs together (the joint fit of
    several recordings: their information added, the body's ``prior`` (:func:`body_prior`) once;
    :func:`covariances`).  Rows and columns of an undetermined combination are inf."""
    info = sum((r.body for r in runs), np.zeros((BODY, BODY))) + prior
    cov: np.ndarray = covariances(info[None])[0]
    return cov


def tensor_std(runs: Sequence[RunInformation], prior: np.ndarray) -> np.ndarray:
    """(6,) kg·m² each tensor entry's σ (:data:`~rig_identification.io.verdict.KEYS` order) from the runs
    together (:func:`combined`)."""
    return np.sqrt(np.abs(np.diag(combined(runs, prior))[:6]))


__all__ = ["BODY", "NOISE_OF_CHANNEL", "RATE_OF_CHANNEL", "SINGULAR", "RunInformation", "SimulatedRun",
           "body_covariance", "body_prior", "channel_noise", "combined", "covariances", "nominal_parameters",
           "record_covariance", "run_information", "simulate_run", "tensor_bound", "tensor_covariance", "tensor_std",
           "true_parameters"]
