"""Whether a diagnosed effect can be the physics in a recording: the range each effect's
parameters must fall in to be named (:data:`PLAUSIBLE`, with units), and the further
conditions on the masses, the exciter's rotor and the share of a dissipative effect's moment
(:func:`implausible`).  :func:`~rig_identification.diagnosis.selection.diagnose` marks each
effect of a combination with it; :func:`~rig_identification.pipeline.offline.with_diagnosis`
names no combination that holds an implausible effect.
"""
from __future__ import annotations

import numpy as np

from ..io.export import EFFECT_UNITS

PLAUSIBLE = {
    "viscous_damping": {"angular": (0.0, np.inf), "linear": (0.0, np.inf)},
    "air_drag": {"angular": (0.0, np.inf), "linear": (0.0, np.inf)},
    "coulomb_friction": {"torque": (0.0, np.inf), "force": (0.0, np.inf)},
    "sensor_delay": {"delay": (-0.1, 0.1)},
    "load_cell_scale": {"scale": (0.8, 1.25)},
    "gyro_bias": {"bias": (-0.05, 0.05)},
    "gyro_scale": {"scale": (0.9, 1.1)},
    "gyro_bias_drift": {"random_walk": (0.0, 1e-2), "bias_range": (0.0, 0.05)},
    "structural_mode": {"frequency": (3.0, 45.0), "damping_ratio": (1e-3, 0.3), "participation": (0.0, 2.0)},
    "accelerometer_bias": {"bias": (-0.5, 0.5)},
    "imu_misalignment": {"rpy": (-0.1, 0.1)},
    "imu_offset": {"offset": (-1.0, 1.0)},
    "cg_offset": {"offset": (-0.25, 0.25)},
    "cable_elasticity": {"stiffness": (1e4, 1e9)},
    "gyroscopic_coupling": {"scale": (0.5, 1.5)},
}
"""The range (SI, in the units of :data:`~rig_identification.io.export.EFFECT_UNITS`) each
effect's parameters must fall in to be named: a fit that needs a dissipation of the wrong sign, a
sensor delay of a tenth of a second or an IMU a metre from
where rig.yaml puts it has found a stand-in for other physics, not the effect.  Units:
rad/s (gyro bias, the drift's ``bias_range`` over the window), rad/s/√s (the drift's
``random_walk``: a MEMS gyro's rate random walk is 1e-5–1e-3), m/s², m, rad, s, N/m, Hz (a
structural mode's frequency: the range searched above the band,
:data:`~rig_identification.diagnosis.structural.F_MIN`–``F_MAX``); scales, damping ratios and
participations are dimensionless (1 = the full base-excited oscillator).  Besides:
``cable_mass`` between 0 and 5 % of the body's mass per cable, ``body_mass`` within 10 %
of rig.yaml's, the exciter's rotor ``unbalance`` within 0.3–3× the mass that makes the
measured force (F / (2π f)²), and a dissipative effect's moment at most
:data:`MAX_EFFECT_SHARE` of the measured moment (RMS in the band: a rig's damping is small)."""
MAX_EFFECT_SHARE = 0.3
CG_PRIOR_CHI2 = 14.16   # χ²₃ at 99.73 % (3 σ): a CG offset must be this likely under the static test's σ


def implausible(entry: dict, rig, effect_share: float | None = None, unbalance: float | None = None,
                cg_covariance: np.ndarray | None = None) -> str | None:
    """Why the effect ``entry`` (of :attr:`Diagnosis.effects`) cannot be the physics in the
    recording (see :data:`PLAUSIBLE`), or None when it is plausible.  cg_covariance: (3, 3) m²
    of the CG the recording was given (a static test's): a ``cg_offset`` must lie within the
    χ²₃ 99.73 % ellipsoid of it (3 σ).  effect_share: the RMS
    of its moment over the measured moment's; unbalance: kg·m that makes the measured
    exciter force."""
    name, par = entry["name"], entry["parameters"]
    for k, (lo, hi) in PLAUSIBLE.get(name, {}).items():
        v = np.atleast_1d(np.asarray(par.get(k, 0.0), float))
        if np.any(v < lo) or np.any(v > hi):
            unit = EFFECT_UNITS.get(name, {}).get(k, "").strip("()")
            return f"{k} = {fmt_value(par.get(k))} outside {lo:g}…{hi:g}" + (f" {unit}" if unit else "")
    if name == "cable_mass" and not 0.0 <= par.get("mass", 0.0) <= 0.05 * rig.mass:
        return f"mass {par['mass']:.3g} kg per cable outside 0…{0.05 * rig.mass:.3g} kg"
    if name == "cg_offset" and cg_covariance is not None:
        dl = np.asarray(par.get("offset", np.zeros(3)), float)
        m2 = float(dl @ np.linalg.pinv(np.asarray(cg_covariance, float)) @ dl)
        if m2 > CG_PRIOR_CHI2:
            return (f"offset {fmt_value(dl)} m beyond 3 σ of the static test's CG (Mahalanobis² {m2:.3g} > "
                    f"{CG_PRIOR_CHI2:.3g})")
    if name == "body_mass" and abs(par.get("mass_error", 0.0)) > 0.1 * rig.mass:
        return f"mass error {par['mass_error']:.3g} kg beyond 10 % of rig.yaml's {rig.mass:.6g} kg"
    if name == "exciter_rotor" and unbalance:
        u = par.get("unbalance", 0.0)
        if not 0.3 * unbalance <= u <= 3.0 * unbalance:
            return f"unbalance {u:.3g} kg·m outside 0.3–3× the {unbalance:.3g} kg·m that makes the measured force"
    if name in ("viscous_damping", "air_drag", "coulomb_friction") and effect_share is not None \
            and effect_share > MAX_EFFECT_SHARE:
        return (f"its moment is {100 * effect_share:.0f} % of the measured moment "
                f"(at most {100 * MAX_EFFECT_SHARE:.0f} %)")
    return None


DETERMINED = {"imu_offset": {"offset": 0.0}, "cg_offset": {"offset": 0.0},
              "imu_misalignment": {"rpy": 0.0}, "sensor_delay": {"delay": 0.0},
              "gyro_bias": {"bias": 0.0}, "accelerometer_bias": {"bias": 0.0}, "gyro_scale": {"scale": 1.0},
              "load_cell_scale": {"scale": 1.0}, "body_mass": {"mass_error": 0.0}, "cable_mass": {"mass": 0.0},
              "exciter_rotor": {"unbalance": 0.0}, "viscous_damping": {"linear": 0.0, "angular": 0.0},
              "air_drag": {"linear": 0.0, "angular": 0.0}, "coulomb_friction": {"torque": 0.0, "force": 0.0}}
"""Each effect's parameters and the value at which the effect is absent: a named effect must
stand :data:`DETERMINED_Z` σ away from it in some component (:func:`undetermined`)."""
DETERMINED_Z = 3.0
PRACTICAL_FLOOR = {"imu_offset": 0.005, "imu_misalignment": 0.001, "sensor_delay": 0.001,
                   "cg_offset": 0.002}   # m, rad, s, m
"""The engineering resolution of a sensor-pose, timing or CG error (the norm of its parameter: 5 mm,
1 mrad, 1 ms, 2 mm): a statistically but not physically significant term is not a finding."""


def undetermined(entry: dict) -> str | None:
    """Why the effect ``entry`` (its ``parameters`` and ``parameters_std``, the joint fit's) is
    not determined by the recording, or None: no component of its parameters (:data:`DETERMINED`)
    lies :data:`DETERMINED_Z` σ from the value at which the effect is absent (a Wald test,
    Ljung 1999 ch. 9), or its size is below :data:`PRACTICAL_FLOOR`."""
    name, par, std = entry["name"], entry["parameters"], entry.get("parameters_std") or {}
    null = DETERMINED.get(name)
    if null:
        z = 0.0
        for k, v0 in null.items():
            if k not in par or k not in std:
                continue
            v, s = np.atleast_1d(np.asarray(par[k], float)) - v0, np.atleast_1d(np.asarray(std[k], float))
            ok = s > 0
            z = max(z, float(np.max(np.abs(v[ok]) / s[ok], initial=0.0)))
        if z < DETERMINED_Z:
            return (f"not determined by the recording: within {DETERMINED_Z:g} σ of no effect "
                    f"(largest |value|/σ {z:.2g})")
    if name in PRACTICAL_FLOOR:
        k = next(iter(DETERMINED[name]))
        size = float(np.linalg.norm(np.atleast_1d(np.asarray(par.get(k, 0.0), float))))
        if size < PRACTICAL_FLOOR[name]:
            return f"{k} {fmt_value(par.get(k))} below the engineering resolution {PRACTICAL_FLOOR[name]:g} (SI)"
    return None


def fmt_value(v) -> str:
    """A parameter value of an effect's JSON as text (numbers to 4 digits; lists, dicts)."""
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {fmt_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(fmt_value(x) for x in v) + "]"
    if isinstance(v, (float, np.floating)):
        return f"{v:.4g}"
    return str(v)
