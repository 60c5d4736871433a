"""The result of the static experiment's CG fit: :class:`CgResult` (the CG with its σ, σ budget,
sensitivities and validation), the fitted pose of each state (:class:`StatePose`), and the
schema of its JSON (``rig-identify cg --json``, read back by :func:`~.handover.load_cg_result`).

Frames and units: CG in the body frame, poses in the world frame (z up); SI units.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from .validation import CgValidation


def _rpy(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R).as_euler("xyz")


# --- result ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class StatePose:
    """Fitted equilibrium of one state: position (3,) world m of the body origin, rotation
    (3, 3) body -> world, rpy (3,) fixed-axis XYZ rad, tensions (N,) N (true, i.e. κ·reading),
    measured/predicted/normalised residuals of the streams used."""

    label: str
    position: np.ndarray
    rotation: np.ndarray
    tensions: np.ndarray
    added_mass: float
    window: tuple[float, float]
    residuals: dict

    @property
    def rpy(self) -> np.ndarray:
        return _rpy(self.rotation)


CG_RESULT_SCHEMA = "rig_identification.cg_result"   # the JSON of CgResult.to_dict / rig-identify cg --json
CG_RESULT_SCHEMA_VERSION = 1
CG_RESULT_UNITS = {
    "center_of_gravity": "m", "center_of_gravity_std": "m", "center_of_gravity_std_noise": "m",
    "center_of_gravity_covariance": "m^2", "mass": "kg", "mass_std": "kg", "mass_from_load_cells": "kg",
    "mass_from_load_cells_std": "kg", "mass_fitted": "kg", "mass_fitted_std": "kg", "load_cell_gain": "1",
    "load_cell_gain_std": "1", "cable_stiffness": "N/m", "cable_stiffness_std": "N/m", "cable_compliance": "m/N",
    "cable_compliance_std": "m/N", "inclinometer_offset": "rad", "states.position": "m (world)",
    "states.rpy": "rad (fixed-axis XYZ, body -> world)", "states.tensions": "N", "states.added_mass": "kg",
    "states.window": "s (header stamps)", "states.residuals_sigma": "1 (residual / its σ)",
    "weakly_determined.std": "m", "weakly_determined.tilt_change_rad": "rad",
    "sensitivity": "m per m of rig.yaml's value (dummy_mass: m/kg)", "uncertainty.geometry_std": "m (dummy_mass: kg)",
    "uncertainty.budget": "m", "validation.checks.statistic": "see each check's detail (σ, χ²/dof)"}


@dataclass(frozen=True)
class CgResult:
    """The static experiment's estimate.

    center_of_gravity (3,) body frame m; center_of_gravity_std (3,) m and covariance (3, 3) m²:
    the measurement noise AND the rig's geometry as surveyed (``geometry_std``: the σ assumed
    for the anchors, cable lengths m, dummy position m and dummy mass kg, see
    :class:`~.model.CgOptions`);
    center_of_gravity_std_noise (3,) m: the measurement noise alone (the geometry taken as
    exact, what the fit reported before geometry σ were assumed); budget: the σ (3,) m each
    source contributes -- ``measurement_noise``, ``scale``, ``cable_lengths``, ``dummy_position``,
    ``dummy_mass``, ``ceiling_anchors``, ``body_anchors`` (those fitted) -- which add in
    quadrature to center_of_gravity_std;
    mass: the scale's reading (rig.yaml) kg with mass_std (the σ assumed for it);
    mass_from_load_cells (sum of the baseline's vertical tension components / g) kg with its
    std, or None without load cells -- a warning says when it and the scale disagree by more
    than 3 combined σ; mass_fitted: the body mass of the fit (with load cells: theirs, times
    the gain the dummy mass calibrates; without: the scale's); load_cell_gain (κ: true tension = κ · reading)
    and std, or None; cable_compliance m/N (std): the fitted common compliance of the cables
    without a stiffness in rig.yaml, or None, and cable_stiffness = its inverse N/m (None when
    the compliance is not significantly > 0, e.g. inextensible cables); states: the fitted
    :class:`StatePose` of each state;
    chi2, dof of the fit; weakly_determined: the CG direction the data determine worst
    (axis, direction, std, tilt change); sensitivity: ∂CG/∂(rig.yaml value) of each systematic
    input, the same definition whether the input is fitted with its σ or taken as exact --
    ``dummy_position`` (3, 3) m/m (first dummy state), ``dummy_mass`` (3,) m/kg,
    ``cable_lengths`` (3, N) m/m, ``ceiling_anchors`` and ``body_anchors`` (3, 3N) m/m (cable
    by cable, x y z); validation: the :class:`CgValidation`; warnings: texts for the user.
    """

    center_of_gravity: np.ndarray
    center_of_gravity_std: np.ndarray
    covariance: np.ndarray
    mass: float
    mass_std: float
    mass_from_load_cells: float | None
    mass_from_load_cells_std: float | None
    mass_fitted: float
    mass_fitted_std: float
    load_cell_gain: float | None
    load_cell_gain_std: float | None
    cable_stiffness: float | None
    cable_stiffness_std: float | None
    cable_compliance: float | None
    cable_compliance_std: float | None
    inclinometer_offset: np.ndarray | None
    states: list[StatePose]
    chi2: float
    dof: int
    inflation: float
    weakly_determined: dict
    warnings: list[str]
    parameter_names: list[str]
    parameter_covariance: np.ndarray
    streams: list[str]
    sensitivity: dict = field(default_factory=dict)
    center_of_gravity_std_noise: np.ndarray | None = None
    geometry_std: dict = field(default_factory=dict)
    budget: dict = field(default_factory=dict)
    validation: CgValidation | None = None

    def without(self, mass: float, cg) -> tuple[np.ndarray, np.ndarray]:
        """CG (3,) and σ (3,) body frame m of the suspended body minus a known part (e.g. the
        carrying frame: ``mass`` kg with its CG ``cg`` (3,) body m), using the scale mass."""
        M = self.mass
        k = M / (M - mass)
        c = (M * self.center_of_gravity - mass * np.asarray(cg, float)) / (M - mass)
        return c, k * self.center_of_gravity_std

    def to_dict(self) -> dict:
        """JSON-ready mapping (lists and floats only): the file format ``rig-identify cg --json``
        prints, ``schema`` :data:`CG_RESULT_SCHEMA` version :data:`CG_RESULT_SCHEMA_VERSION`,
        ``units`` per field (:data:`CG_RESULT_UNITS`); read back by :func:`~.handover.load_cg_result`."""
        def f(x):
            return None if x is None else float(x)

        def v(a):
            return None if a is None else [float(x) for x in np.ravel(a)]
        return {
            "schema": CG_RESULT_SCHEMA, "schema_version": CG_RESULT_SCHEMA_VERSION, "units": dict(CG_RESULT_UNITS),
            "center_of_gravity": v(self.center_of_gravity),
            "center_of_gravity_std": v(self.center_of_gravity_std),
            "center_of_gravity_covariance": [v(r) for r in self.covariance],
            "frame": "body",
            "mass": f(self.mass), "mass_std": f(self.mass_std),
            "mass_from_load_cells": f(self.mass_from_load_cells),
            "mass_from_load_cells_std": f(self.mass_from_load_cells_std),
            "mass_fitted": f(self.mass_fitted), "mass_fitted_std": f(self.mass_fitted_std),
            "load_cell_gain": f(self.load_cell_gain), "load_cell_gain_std": f(self.load_cell_gain_std),
            "cable_stiffness": f(self.cable_stiffness), "cable_stiffness_std": f(self.cable_stiffness_std),
            "cable_compliance": f(self.cable_compliance), "cable_compliance_std": f(self.cable_compliance_std),
            "inclinometer_offset": v(self.inclinometer_offset),
            "states": [{"label": s.label, "position": v(s.position), "rpy": v(s.rpy),
                        "tensions": v(s.tensions), "added_mass": f(s.added_mass),
                        "window": v(s.window),
                        "residuals_sigma": {k: v(r["normalised"]) for k, r in s.residuals.items()}}
                       for s in self.states],
            "streams": list(self.streams),
            "chi2": f(self.chi2), "dof": int(self.dof), "sigma_inflation": f(self.inflation),
            "weakly_determined": self.weakly_determined,
            "sensitivity": {k: np.asarray(val).tolist() for k, val in self.sensitivity.items()},
            "center_of_gravity_std_noise": v(self.center_of_gravity_std_noise),
            "uncertainty": {
                "center_of_gravity_std": "measurement noise and the rig's geometry (geometry_std)",
                "center_of_gravity_std_noise": "measurement noise alone (geometry taken as exact)",
                "geometry_std": dict(self.geometry_std),
                "budget": {k: v(val) for k, val in self.budget.items()}},
            "validation": None if self.validation is None else self.validation.to_dict(),
            "warnings": list(self.warnings),
        }
