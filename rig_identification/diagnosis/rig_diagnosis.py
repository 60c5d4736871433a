"""What the fitted rig model leaves out, named only where the recording tells it apart.

Two kinds of finding.  Data errors come first: they are unknowns of the model itself.

* **Data errors** — an unknown that has a prior (the mass, the CG from the static test, each
  cable's stiffness, each load cell's gain, every surveyed anchor coordinate and cable length)
  and that the data pull more than :data:`CONFLICT_SIGMA` of the prior's σ off its centre: a
  wrong rig.yaml or static result, found and corrected by the fit itself (:class:`PriorConflict`),
  listed where every channel fits.
* **Physics and sensor traits** the model leaves out — the extensions of
  :data:`~rig_identification.estimation.rig_unknowns.EXTENSIONS` — tried one at a time at the
  estimate (:class:`~rig_identification.estimation.rig_extensions.LinearisedRig`: the score test,
  every rigid-body unknown refitted).  An extension is a candidate where it is *significant* (its
  fall of χ² beyond the χ² quantile :data:`SIGNIFICANCE`), *determined* (a value beyond
  :data:`DETERMINED_Z` of its σ), *plausible* (:func:`plausible`) and *cross-validated* (fitted on
  either half of the record it lowers χ² on the other).  The best
  candidate is *named* only where Vuong's test tells it apart from every other candidate (|z| above
  Student's t at 97.5 %); otherwise the step names the class — the best and those it cannot be
  told from — and the model takes its simplest member (fewest unknowns), so the tensor is still
  corrected.  The model is then refitted with it (the caller's ``refit``, from its linearised
  estimate), and further extensions are tested at the refit's estimate, each only as above (at
  most :data:`MAX_EXTENSIONS`; one whose refit does not lower the misfit is left out).  Where the
  last refit still leaves a channel beyond
  :data:`~rig_identification.estimation.rig_fit.REWEIGHT_LIMIT` of its noise nothing is added: the
  motion is still not found, and any extension lowers such a misfit somewhat; then an extension
  whose start the recording gives (the exciter rotor's unbalance, from the measured force) is
  fitted from that start, and tested at its own fit where it finds the motion
  (:func:`restart_step`).  Where it leaves one beyond
  :data:`~rig_identification.estimation.rig_fit.LEVEL_LIMIT` (the fit's own ``model_error``) the
  extensions stay in the model but nothing is named (:attr:`RigDiagnosis.named`): they lowered a
  misfit they do not explain (on the package's simulator a structural mode at 8 Hz took
  imu_offset and gyro_scale), and the advice says so — but for an extension, told apart, whose
  values another sensor measures and the last fit confirms (:func:`confirms`: the rotor's
  unbalance, which the exciter's force gives and the body's motion asks for within its σ): two
  sensors agree on its physics, and it is named beside the misfit.  The rig
  model already holds viscous damping; where it is significant,
  quadratic drag and the ceiling pins' dry friction are tried in its place, and said indistinguishable from it
  where Vuong's test cannot tell them apart (at one forcing amplitude they are nearly the same
  force).  The damping, its class or a name, is reported only where it passes an extension's
  tests too: no term below zero beyond 3 σ, and fitted on either half it lowers χ² on the other
  (:attr:`Damping.found`).

The gyro's constant bias is the offset the fit removes from its channels (no physics of a body
hanging on cables makes a mean rate): named ``gyro_bias`` where the recording determines it
(:class:`GyroBias`).

The last refit's tensor is the estimate, and each channel's residual before and after shows the
fit improve.  The data errors are those of the last fit.  Where the fit with the extensions leaves
the tensor undetermined, or the first rigid-body fit had lost the motion and an extension added is
not determined at the refit, the rigid-body model fitted again from its tensor must still misfit
for anything to be named (:func:`diagnose_rig`).  Where the rigid-body fit explains the recording and
leaves the tensor undetermined, no extension is tested; what the model itself holds — its viscous
damping (where no other minimum fits as well) and the gyro's bias — is still read and named as
above.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2, norm, t

from ..estimation.harmonic_start import DampedStart, ForcedResponseStart, drag_start
from ..estimation.rig_extensions import ExtensionFit, LinearisedRig
from ..estimation.rig_fit import LEVEL_LIMIT, REWEIGHT_LIMIT, SANDWICH_BLOCKS, RigFit, fitted_force
from ..estimation.rig_problem import NON_NEGATIVE as FIT_NON_NEGATIVE
from ..estimation.rig_record import Record
from ..estimation.rig_unknowns import EXTENSIONS, Prior, labels, priors
from ..io.verdict import Z95

log = logging.getLogger(__name__)

#: An extension is significant where its fall of χ² exceeds this quantile of χ² with its unknowns'
#: count of degrees of freedom (one test per extension of the library: 0.999 keeps the family's
#: false alarms near 1 %).
SIGNIFICANCE = 0.999
#: A candidate's values are determined where one of them lies beyond this many of its σ: the
#: normal quantile of :data:`SIGNIFICANCE`, two-sided (3.29; what the χ² test asks of one unknown).
DETERMINED_Z = float(norm.ppf(0.5 + SIGNIFICANCE / 2))
#: Vuong's z beyond Student's t at this level (SANDWICH_BLOCKS − 1 degrees of freedom) tells two
#: explanations apart.
APART_LEVEL = 0.975
#: A value the motion gives an extension confirms the one another sensor measures (:func:`confirms`)
#: where the two differ by less than Z95 of its σ plus this share of the measured one (the force's
#: median amplitude over its mean Ω², taken where the spin wanders a little).
CONFIRM_SHARE = 0.01
#: What another sensor measures of an extension (:func:`measured_values`): name -> value index ->
#: (the value's unit and name, the sensor's reading of it).
MEASURED = {"exciter_rotor": {0: ("kg·m of unbalance", "the exciter's force on the body over Ω² gives")}}
#: Extensions the selection adds at most.
MAX_EXTENSIONS = 3
#: A prior is in conflict with the data where the estimate lies more than this many of its σ off.
CONFLICT_SIGMA = 3.0
#: Viscous damping counts as found where one of its two terms exceeds this many σ.
DAMPING_SIGMA = 3.0
#: Physical bounds of each extension's values (plausible): at most this in size (the IMU's offset:
#: its change from rig.yaml's position).
BOUNDS = {"load_cell_delay": 0.1, "exciter_delay": 0.1, "imu_offset": 0.5, "gyro_scale": 0.05, "gyro_bias_drift": 1e-3}
#: Extensions whose every value is ≥ 0: the dampings the fit holds there, and the unbalance (its
#: mass lies toward the force it makes).
NON_NEGATIVE = FIT_NON_NEGATIVE + ("exciter_rotor",)
#: What tells two candidates apart (:meth:`RigDiagnosis.advice`), by the pair's class.
DAMPING = ("viscous_damping", "air_drag", "pivot_friction")
APART_ADVICE = {
    "damping": "a run at a second forcing amplitude (viscous, quadratic and dry friction scale differently with "
               "the swing's speed)",
    "other": "a run at another exciter frequency or position (rig-identify plan)",
}
#: What tells two candidates apart where their physics says more than :data:`APART_ADVICE`'s
#: "other" (:func:`apart_advice`).
PAIR_ADVICE = {
    frozenset(("load_cell_delay", "exciter_delay")):
        "a tap on the frame that every sensor records (one event in every stream: the load cells' clock against "
        "the exciter's and the IMU's)",
    frozenset(("imu_offset", "gyro_scale")):
        "a run at another exciter frequency (an IMU offset's lever arm reads the angular acceleration, ω² times "
        "the swing; a gyro scale error a share of the rate, ω times it)",
    frozenset(("gyro_bias_drift", "gyro_scale")):
        "a still span before and after the run (a drifting bias shows where the body does not turn; a scale error "
        "does not)",
}


@dataclass(frozen=True)
class Candidate:
    """One extension's test at one step (:mod:`~rig_identification.estimation.rig_extensions`).

    name: :data:`~rig_identification.estimation.rig_unknowns.EXTENSIONS`'s.  statistic: the fall
    of χ², dof its degrees of freedom, threshold the χ² quantile it must exceed.  values, std: its
    unknowns' linearised estimate and σ (units of EXTENSIONS).  held_out: (2,) the fall of χ² on
    each half of the record, fitted on the other.  plausible: :func:`plausible`.
    """

    name: str
    statistic: float
    dof: int
    threshold: float
    values: np.ndarray
    std: np.ndarray
    held_out: np.ndarray
    plausible: bool

    @property
    def significant(self) -> bool:
        return self.statistic > self.threshold

    @property
    def cross_validated(self) -> bool:
        return bool(np.all(self.held_out > 0))

    @property
    def determined(self) -> bool:
        """Some value of the extension lies beyond :data:`DETERMINED_Z` of its σ: the recording
        determines the extension itself, not only the joint fall of χ² of its unknowns (two
        unknowns each within 3 σ can pass the χ² test together)."""
        return bool(np.any(np.abs(self.values) > DETERMINED_Z * self.std))

    @property
    def eligible(self) -> bool:
        return self.significant and self.plausible and self.cross_validated and self.determined

    def to_dict(self) -> dict:
        return {"name": self.name, "chi2_fall": self.statistic, "dof": self.dof, "threshold": self.threshold,
                "values": self.values.tolist(), "std": self.std.tolist(), "units": EXTENSIONS[self.name][1],
                "held_out_chi2_fall": self.held_out.tolist(), "significant": self.significant,
                "plausible": self.plausible, "cross_validated": self.cross_validated, "determined": self.determined}


@dataclass(frozen=True)
class Step:
    """One extension added to the model: ``added``, and ``indistinguishable`` the eligible
    candidates Vuong's test could not tell from the best (then ``added`` is the simplest of the
    class); ``vuong``: z of the best against each other eligible candidate; ``candidates``: every
    test of the step.  ``restart``: the step came from a fit started with the extension at the
    value the recording gives it (:func:`restart_step`), where the rigid-body fit had not found the
    motion; its tests are then made at that fit, the others' in its place.  ``measured``: value
    index -> what another sensor measures of it (:func:`measured_values`)."""

    added: str
    best: str
    indistinguishable: tuple[str, ...]
    vuong: dict[str, float]
    candidates: tuple[Candidate, ...]
    restart: bool = False
    measured: dict[int, float] = field(default_factory=dict)

    @property
    def named(self) -> bool:
        """The step's extension is told apart from every other candidate."""
        return not self.indistinguishable

    def to_dict(self) -> dict:
        return {"added": self.added, "best": self.best, "named": self.named,
                "indistinguishable": list(self.indistinguishable), "vuong_z": self.vuong,
                "candidates": [c.to_dict() for c in self.candidates], "restart": self.restart,
                "measured": {str(i): v for i, v in self.measured.items()}}


def confirms(values: np.ndarray, std: np.ndarray, measured: dict[int, float]) -> bool:
    """Whether an extension's fitted ``values`` (σ ``std``, units of
    :data:`~rig_identification.estimation.rig_unknowns.EXTENSIONS`) are what another sensor
    measures of them (``measured``: value index -> value), each within Z95 of its σ plus
    :data:`CONFIRM_SHARE` of the measured value: two sensors agree on the extension's physics (the
    body's motion and the exciter's force on the rotor's unbalance), which a term that only soaks
    up a misfit would not (on the package's simulator without a rotor, its unbalance fitted from
    the force's falls to zero within its σ: test_rig_diagnosis).  False where nothing is measured."""
    return bool(measured) and all(abs(values[i] - v) <= Z95 * std[i] + CONFIRM_SHARE * abs(v)
                                  for i, v in measured.items())


@dataclass(frozen=True)
class Damping:
    """The model's viscous damping and what else would explain it.

    z: (2,) c/σ of its linear and angular terms.  alternatives: Vuong's z of
    the viscous model against each of ``air_drag`` and ``pivot_friction`` put in its place
    (positive: viscous fits better); indistinguishable: those within Student's t at 97.5 %.
    held_out: (2,) the fall of χ² on each half of the record of the damping fitted on the other
    (:meth:`~rig_identification.estimation.rig_extensions.LinearisedRig.held_out`)."""

    z: np.ndarray
    alternatives: dict[str, float]
    indistinguishable: tuple[str, ...]
    held_out: np.ndarray

    @property
    def significance(self) -> np.ndarray:
        """(2,) |c|/σ of the linear and angular terms."""
        return np.abs(self.z)

    @property
    def plausible(self) -> bool:
        """No term below zero beyond 3 σ (a damping takes energy out: :func:`plausible`'s rule)."""
        return bool(np.all(self.z > -3.0))

    @property
    def cross_validated(self) -> bool:
        return bool(np.all(self.held_out > 0))

    @property
    def found(self) -> bool:
        """The damping passes what a named extension must (module docstring): a term beyond
        :data:`DAMPING_SIGMA`, plausible and cross-validated.  Where it is significant and fails
        another test, it absorbs a misfit it does not explain (bench_trust's clean 7501: the
        tensor undetermined, linear damping +10 σ, angular −3.3 σ), and no damping is named."""
        return bool(np.any(self.significance > DAMPING_SIGMA)) and self.plausible and self.cross_validated

    def to_dict(self) -> dict:
        return {"significance_sigma": self.significance.tolist(), "z": self.z.tolist(),
                "vuong_z_viscous_over": self.alternatives, "indistinguishable": list(self.indistinguishable),
                "held_out_chi2_fall": self.held_out.tolist(), "plausible": self.plausible,
                "cross_validated": self.cross_validated, "found": self.found}


#: The gyro's channels (:func:`~rig_identification.estimation.rig_record.channel_names`).
GYRO_CHANNELS = ("gyro_x", "gyro_y", "gyro_z")


@dataclass(frozen=True)
class GyroBias:
    """The gyro's constant bias: the offset the fit removed from its channels
    (:attr:`~rig_identification.estimation.rig_fit.RigFit.offsets`), values (3,) rad/s IMU axes,
    std (3,) their σ (:func:`~rig_identification.estimation.rig_fit.channel_offsets`: from the
    scatter of the blocks' means, Student's t with SANDWICH_BLOCKS − 1 degrees of freedom).
    A body hanging on cables has no mean rate, but the Earth turns at 7.3e-5 rad/s: a gyro fine
    enough to resolve that reads it as a bias too."""

    values: np.ndarray
    std: np.ndarray

    @property
    def z(self) -> np.ndarray:
        """(3,) each axis's bias over its σ."""
        return self.values / self.std

    @property
    def threshold(self) -> float:
        """Student's t (SANDWICH_BLOCKS − 1 degrees of freedom) at :data:`SIGNIFICANCE`, two-sided,
        over three axes (Bonferroni): one test per recording, as an extension's."""
        return float(t.ppf(1 - (1 - SIGNIFICANCE) / 6, SANDWICH_BLOCKS - 1))

    @property
    def found(self) -> bool:
        """An axis's bias lies beyond :attr:`threshold` of its σ."""
        return bool(np.any(np.abs(self.z) > self.threshold))

    def to_dict(self) -> dict:
        return {"values": self.values.tolist(), "std": self.std.tolist(), "units": "rad/s, IMU axes",
                "z": self.z.tolist(), "threshold": self.threshold, "found": self.found}


def gyro_bias(fit: RigFit) -> GyroBias | None:
    """The gyro's bias in ``fit`` (:class:`GyroBias`), None where the fit carries no offsets."""
    if fit.offsets is None or fit.offset_std is None:
        return None
    idx = [fit.channels.index(c) for c in GYRO_CHANNELS]
    return GyroBias(fit.offsets[idx], fit.offset_std[idx])


@dataclass(frozen=True)
class PriorConflict:
    """An unknown the data pull off its prior: ``unknown`` (its label), ``estimate`` and ``prior``
    (its centre) with σ ``prior_std`` and the estimate's ``std`` (stiffness: N/m, from the log),
    ``z`` = (estimate − prior) / prior_std in the fitted unknown."""

    unknown: str
    estimate: float
    std: float
    prior: float
    prior_std: float
    z: float

    def to_dict(self) -> dict:
        return {"unknown": self.unknown, "estimate": self.estimate, "std": self.std, "prior": self.prior,
                "prior_std": self.prior_std, "z": self.z}


def evidenced(fit: RigFit, steps: list[Step]) -> bool:
    """Every extension the ``steps`` added is determined at ``fit`` (the fit with them): one of
    its values beyond :data:`DETERMINED_Z` of its σ (Wald's test at the refit's estimate)."""
    return all(bool(np.any(np.abs(v) > DETERMINED_Z * sd)) for v, sd in (fit.extension(s.added) for s in steps))


def lost(fit: RigFit) -> bool:
    """The fit has not found the motion: a channel beyond
    :data:`~rig_identification.estimation.rig_fit.REWEIGHT_LIMIT` of its noise (its estimate is no
    minimum, and no test at it is evidence)."""
    return bool(np.max(fit.residual_level) > REWEIGHT_LIMIT)


@dataclass(frozen=True)
class RigDiagnosis:
    """What :func:`diagnose_rig` found: the data errors (``conflicts``), the viscous damping's
    alternatives (``damping``, None where it is not significant), the extensions added step by
    step (``steps``), the refit with them (``refit``, None where none was added) and the fit it
    started from (``rigid``); ``determined``: whether the fit determined the tensor (where it did
    not, no extension was tested: :func:`diagnose_rig`)."""

    conflicts: tuple[PriorConflict, ...]
    damping: Damping | None
    steps: tuple[Step, ...]
    rigid: RigFit
    refit: RigFit | None
    determined: bool = True

    @property
    def gyro(self) -> GyroBias | None:
        """The gyro's bias in the last fit (:func:`gyro_bias`; None where it carries no offsets)."""
        return gyro_bias(self.refit or self.rigid)

    @property
    def found_motion(self) -> bool:
        """Whether the last fit found the motion (every channel within
        :data:`~rig_identification.estimation.rig_fit.REWEIGHT_LIMIT` of its noise): where it did
        not, nothing is named and no test at it is evidence."""
        return not lost(self.refit or self.rigid)

    @property
    def explained(self) -> bool:
        """Whether the last fit explains the recording: every channel within
        :data:`~rig_identification.estimation.rig_fit.LEVEL_LIMIT` of its noise.  Where it does not,
        what the model holds lowered the misfit without explaining it, and nothing is named."""
        return bool(np.max((self.refit or self.rigid).residual_level) <= LEVEL_LIMIT)

    @property
    def unexplained(self) -> tuple[str, ...]:
        """The channels the last fit leaves beyond :data:`~rig_identification.estimation.rig_fit.LEVEL_LIMIT`
        of their noise."""
        f = self.refit or self.rigid
        return tuple(c for c, v in zip(f.channels, f.residual_level) if v > LEVEL_LIMIT)

    @property
    def extensions(self) -> tuple[str, ...]:
        """The extensions the refit holds."""
        return tuple(s.added for s in self.steps)

    @property
    def named(self) -> tuple[str, ...]:
        """Where the last fit explains the recording (:attr:`explained`): the extensions the
        recording tells apart from every other candidate, ``viscous_damping`` where the model's
        viscous damping is significant and told apart from quadratic drag and the pins' friction in
        its place, and ``gyro_bias`` where the gyro's bias is found (:class:`GyroBias`).  Where it
        does not: only an extension told apart that another sensor confirms (:attr:`confirmed`);
        what else the model holds is not named."""
        if not self.explained:
            return tuple(s.added for s in self.steps if s.named and s.added in self.confirmed) \
                if self.found_motion else ()
        d = self.damping
        viscous = ("viscous_damping",) if d is not None and d.found and not d.indistinguishable else ()
        bias = ("gyro_bias",) if self.gyro is not None and self.gyro.found else ()
        return tuple(s.added for s in self.steps if s.named) + viscous + bias

    @property
    def confirmed(self) -> tuple[str, ...]:
        """The extensions whose values in the last fit another sensor measures and :func:`confirms`
        (the rotor's unbalance: the exciter's force over Ω²)."""
        if self.refit is None:
            return ()
        return tuple(s.added for s in self.steps if s.measured and confirms(*self.refit.extension(s.added), s.measured))

    @property
    def classes(self) -> tuple[tuple[str, ...], ...]:
        """Where the last fit explains the recording: each class the recording does not tell apart
        (the best candidate first, then those it cannot be told from; the damping's with
        ``viscous_damping`` first).  Otherwise none."""
        if not self.explained:
            return ()
        groups = [(s.best,) + s.indistinguishable for s in self.steps if not s.named]
        if self.damping is not None and self.damping.found and self.damping.indistinguishable:
            groups.append(("viscous_damping",) + self.damping.indistinguishable)
        return tuple(groups)

    @property
    def advice(self) -> list[str]:
        """For each class not told apart, what would tell its members apart; where the last fit
        does not explain the recording, that nothing is named and why."""
        if self.found_motion and not self.explained and (self.steps or self.damping is not None):
            held = ", ".join(self.extensions) or "its viscous damping"
            named = self.named
            confirmed = [f"{s.added} is named all the same: the body's motion asks for "
                         + ", ".join(f"{v[i]:.4g} ± {sd[i]:.2g} {MEASURED[s.added][i][0]}" for i in s.measured)
                         + ", " + ", ".join(f"{MEASURED[s.added][i][1]} {m:.4g}" for i, m in s.measured.items())
                         for s in self.steps if s.added in named and self.refit is not None
                         for v, sd in (self.refit.extension(s.added),)]
            rest = "nothing else is named" if named else "nothing is named"
            return [f"the model with {held} still leaves {', '.join(self.unexplained)} beyond {LEVEL_LIMIT:g}× the "
                    "noise: what it leaves out is none of the extensions tested alone (a structural mode, a sprung "
                    f"body, several effects at once?); {rest}"] + confirmed
        out = [] if self.determined else [
            "the tensor is not determined (not_identifiable): the estimate is one of many that fit the recording "
            "as well, so no extension is tested at it; only what the model holds (its damping, the gyro's bias) "
            "is named"]
        for g in self.classes:
            out.append(f"{' or '.join(g)}: not told apart by this recording; {apart_advice(g)}")
        return out

    def to_dict(self) -> dict:
        d: dict = {"determined": self.determined, "found_motion": self.found_motion, "explained": self.explained,
                   "unexplained_channels": list(self.unexplained), "data_errors": [c.to_dict() for c in self.conflicts],
                   "damping": None if self.damping is None else self.damping.to_dict(),
                   "steps": [s.to_dict() for s in self.steps], "extensions": list(self.extensions),
                   "gyro_bias": None if self.gyro is None else self.gyro.to_dict(),
                   "named": list(self.named), "confirmed": list(self.confirmed),
                   "classes": [list(g) for g in self.classes], "advice": self.advice,
                   "residual_level_before": {c: float(v) for c, v in
                                             zip(self.rigid.channels, self.rigid.residual_level)}}
        if self.refit is not None:
            d["residual_level_after"] = {c: float(v) for c, v in zip(self.refit.channels, self.refit.residual_level)}
        return d


def apart_advice(group: tuple[str, ...]) -> str:
    """What would tell the candidates of ``group`` (the best first) apart: the damping class's run
    at a second amplitude (:data:`APART_ADVICE`), else for each other member the pair's
    (:data:`PAIR_ADVICE`) or a run at another exciter frequency or position."""
    if all(e in DAMPING for e in group):
        return f"{APART_ADVICE['damping']} tells them apart"
    ways: dict[str, list[str]] = {}
    for e in group[1:]:
        ways.setdefault(PAIR_ADVICE.get(frozenset((group[0], e)), APART_ADVICE["other"]), []).append(e)
    return "; ".join(f"{way} tells {group[0]} from {', '.join(es)}" for way, es in ways.items())


def plausible(name: str, fit: ExtensionFit) -> bool:
    """The extension's values are physical: a damping or an unbalance not below zero beyond 3 σ;
    a delay, an IMU offset, a gyro's scale error or drift within :data:`BOUNDS`."""
    v, s = fit.values, fit.std
    if name in NON_NEGATIVE:
        return bool(np.all(v > -3 * s))
    size = fit.change if name == "imu_offset" else v
    return bool(np.all(np.abs(size) <= BOUNDS[name]))


def prior_conflicts(fit: RigFit, prior: Prior, cables: list[str]) -> tuple[PriorConflict, ...]:
    """The unknowns with a prior whose estimate lies more than :data:`CONFLICT_SIGMA` of the
    prior's σ off its centre (the mass and the CG the body's, :attr:`~.rig_fit.RigFit.body`), the
    largest first (the exciter force's correction and the state
    left out: their priors only hold the fit's span); none where a channel is beyond
    :data:`~rig_identification.estimation.rig_fit.LEVEL_LIMIT` of its noise (the model does not
    fit: what it pulls off its priors may be the misfit's, not a data error)."""
    if fit.unknowns is None or np.max(fit.residual_level) > LEVEL_LIMIT:
        return ()
    lay = fit.layout
    x = fit.unknowns.copy()
    centre, std = priors(prior, lay, x)
    names = labels(lay, cables)
    post = np.sqrt(np.diag(fit.covariance))
    # the mass's and the CG's priors are the body's (the suspended body less an exciter rotor's mass)
    x[:10], post[:10] = np.r_[fit.body.inertia, fit.body.cg, fit.body.mass], fit.body.std
    out = []
    for i in range(lay.geometry.stop):
        if not np.isfinite(std[i]):
            continue
        z = (x[i] - centre[i]) / std[i]
        if abs(z) > CONFLICT_SIGMA:
            stiff = lay.log_stiffness.start <= i < lay.log_stiffness.stop
            f = np.exp if stiff else float
            estimate, p = float(f(x[i])), float(f(centre[i]))
            out.append(PriorConflict(names[i], estimate, float(estimate * post[i] if stiff else post[i]), p,
                                     float(p * std[i] if stiff else std[i]), float(z)))
    return tuple(sorted(out, key=lambda c: -abs(c.z)))


def _candidates(lin: LinearisedRig) -> dict[str, tuple[Candidate, ExtensionFit]]:
    out = {}
    for e in lin.names:
        f = lin.fitted((e,))
        out[e] = (Candidate(e, f.statistic, f.dof, float(chi2.ppf(SIGNIFICANCE, f.dof)), f.values, f.std,
                            f.held_out, plausible(e, f)), f)
    return out


def next_step(lin: LinearisedRig) -> Step | None:
    """The extension to add to the fitted model ``lin`` linearises, or None where no candidate is
    eligible (module docstring)."""
    tests = _candidates(lin)
    eligible = {e: cf for e, cf in tests.items() if cf[0].eligible}
    if not eligible:
        return None
    apart = float(t.ppf(APART_LEVEL, SANDWICH_BLOCKS - 1))
    best = max(eligible, key=lambda e: eligible[e][0].statistic - eligible[e][0].dof)
    z = {e: lin.vuong(eligible[best][1], eligible[e][1]) for e in eligible if e != best}
    close = tuple(e for e, v in z.items() if v < apart)
    added = min((best,) + close, key=lambda e: (EXTENSIONS[e][0], list(EXTENSIONS).index(e)))
    return Step(added, best, close, z, tuple(c for c, _ in tests.values()))


#: The refit the diagnosis calls: (extensions: name -> the start of its unknowns, the tensor (6,)
#: kg·m² to start from first, the cables' stiffness (N,) N/m to start from or None: the fit's own)
#: -> the fit.
Refit = Callable[[dict[str, np.ndarray], np.ndarray, "np.ndarray | None"], RigFit]


@dataclass(frozen=True)
class PhysicalStart:
    """An extension's start the recording itself gives (:func:`physical_starts`): ``values`` its
    unknowns; ``tensor`` (6,) kg·m² the tensor its fit starts from (None: the rigid fit's);
    ``stiffness`` (N,) N/m the cables' (None: the fit's own start)."""

    values: np.ndarray
    tensor: np.ndarray | None = None
    stiffness: np.ndarray | None = None


def physical_starts(rec: Record, damped: DampedStart | None = None, turning: ForcedResponseStart | None = None
                    ) -> dict[str, PhysicalStart]:
    """The extensions whose unknowns the recording itself gives a start, and that start: the
    exciter's rotor, its unbalance the one that makes the measured force
    (:meth:`~rig_identification.estimation.rig_record.Record.unbalance`; its weight's moment turns
    with it) and its mass 0 (none where the force is not a rotating
    vector), from the tensor and the cables' stiffness of ``turning`` (the forced response with
    that unbalance) where given;
    the air drag, the quadratic drag equivalent at the record's amplitudes to the viscous damping
    the fundamental asks for (``damped``: :func:`~rig_identification.estimation.harmonic_start.damped_start`;
    :func:`~rig_identification.estimation.harmonic_start.drag_start`), where it asks for some,
    from ``damped``'s tensor."""
    out = {}
    unbalance = rec.unbalance()
    if unbalance is not None:
        rotor = np.array([unbalance, 0.0])
        out["exciter_rotor"] = PhysicalStart(rotor) if turning is None else \
            PhysicalStart(rotor, turning.tensor, turning.stiffness)
    if damped is not None and np.any(damped.damping > 0):
        out["air_drag"] = PhysicalStart(drag_start(rec, damped), damped.tensor)
    return out


def measured_values(rec: Record, prior: Prior, fit: RigFit) -> dict[str, dict[int, float]]:
    """What another sensor than the motion's measures of the extensions ``fit`` holds (name ->
    value index -> value, units of :data:`~rig_identification.estimation.rig_unknowns.EXTENSIONS`):
    the exciter rotor's unbalance (index 0), the median amplitude over Ω² of the force on the body
    as the fit infers it from the exciter's readings
    (:meth:`~rig_identification.estimation.rig_record.Record.unbalance` of
    :func:`~rig_identification.estimation.rig_fit.fitted_force`: the readings hold the force less
    the rotor's own inertial force, −m_r a_e, which its bearing passes too — a few % of the force on
    the package's simulator's 10 kg rotor, test_rig_diagnosis — and the fit adds it back)."""
    if "exciter_rotor" not in fit.layout.extensions:
        return {}
    unbalance = rec.unbalance(fitted_force(rec, prior, fit))
    return {} if unbalance is None else {"exciter_rotor": {0: unbalance}}


def restart_step(rec: Record, prior: Prior, fit: RigFit, refit: Refit,
                 damped: DampedStart | None = None, turning: ForcedResponseStart | None = None
                 ) -> tuple[Step, RigFit] | None:
    """Where the rigid-body ``fit`` did not find the motion (a channel beyond
    :data:`~rig_identification.estimation.rig_fit.REWEIGHT_LIMIT` of its noise), no test at it is
    evidence, and an extension tried from zero starts where the rigid fit did.  Each extension of
    :func:`physical_starts` (``damped``: the forced response fitted with the body's damping;
    ``turning``: with the exciter rotor's unbalance) is fitted from the start the recording gives
    it (``refit``), its values, tensor and stiffness; the first
    whose fit finds the motion is tested at that fit as a step's candidate is at the rigid fit: the
    model without it (its unknowns at zero, linearised) against the model with it — significant,
    determined, plausible, cross-validated (:meth:`LinearisedRig.held_out`) — and every other
    extension fitted in its place, an eligible one that Vuong's test cannot tell from it making a
    class.  Returns the step and its fit, or None where none finds the motion or passes the tests
    (on the package's simulator a 10 kg rotor on a vertical spin axis: the rigid fit's tensions
    3 300× their noise, the fit from the unbalance every channel within 1.1×)."""
    apart = float(t.ppf(APART_LEVEL, SANDWICH_BLOCKS - 1))
    for name, start in physical_starts(rec, damped, turning).items():
        log.info("diagnosis: the fit did not find the motion; fitting it with %s from %s", name,
                 np.round(start.values, 4))
        after = refit({name: start.values}, fit.parameters.inertia if start.tensor is None else start.tensor,
                      start.stiffness)
        if lost(after):
            log.info("diagnosis: with %s it still does not", name)
            continue
        untried = tuple(e for e in EXTENSIONS if e not in after.layout.extensions)
        lin = LinearisedRig(rec, prior, after, untried)
        index = after.layout.extended(untried).extension_of(name)      # the linearisation's layout
        without = lin.without(index)
        values = lin.x[index]
        std = np.sqrt(np.diag(after.covariance))[after.layout.extension_of(name)]
        own = ExtensionFit((name,), float(without.r @ without.r - lin.r @ lin.r), len(values), values, std, values,
                           lin.held_out(index), lin.r[:lin.rows])
        mine = Candidate(name, own.statistic, own.dof, float(chi2.ppf(SIGNIFICANCE, own.dof)), values, std,
                         own.held_out, plausible(name, own))
        if not mine.eligible:
            log.info("diagnosis: %s found the motion but fails its tests (%s)", name, mine.to_dict())
            continue
        others = _candidates(without)
        z = {e: lin.vuong(own, f) for e, (c, f) in others.items() if c.eligible}
        close = tuple(e for e, v in z.items() if v < apart)
        return Step(name, name, close, z, (mine,) + tuple(c for c, _ in others.values()), restart=True), after
    return None


def damping_alternatives(lin: LinearisedRig, fit: RigFit) -> Damping | None:
    """The viscous damping's alternatives (:class:`Damping`), None where neither of its terms
    exceeds :data:`DAMPING_SIGMA`.  Those ``lin`` tests (``lin.names``) are put in its place: one
    the fit already holds (a step of the diagnosis added it) is beside it, not an alternative."""
    lay = fit.layout
    c = fit.parameters.body_damping
    sd = np.sqrt(np.diag(fit.covariance)[lay.body_damping])
    z_c = c / sd
    if not np.any(np.abs(z_c) > DAMPING_SIGMA):
        return None
    apart = float(t.ppf(APART_LEVEL, SANDWICH_BLOCKS - 1))
    without = lin.without(lay.body_damping)
    z: dict[str, float] = {e: lin.vuong(lin.base(), without.fitted((e,))) for e in ("air_drag", "pivot_friction")
                           if e in lin.names}
    return Damping(z_c, z, tuple(e for e, v in z.items() if v < apart), lin.held_out(lay.body_damping))


def _extended(rec: Record, prior: Prior, steps: list[Step], fit: RigFit,
              refit: Refit | None
              ) -> tuple[list[Step], RigFit, LinearisedRig]:
    """``fit`` (``steps`` made it) with the extensions added step by step (:func:`next_step`, each
    refitted from ``fit``'s tensor while it lowers the misfit, at most :data:`MAX_EXTENSIONS` in
    all; none on a fit with an extension that has not found the motion: an extension is added to
    a found one only): the steps, the last fit and its linearisation."""
    steps, current = list(steps), fit
    while True:
        untried = tuple(e for e in EXTENSIONS if e not in current.layout.extensions)
        lin = LinearisedRig(rec, prior, current, untried)
        if steps and lost(current):
            return steps, current, lin
        step = next_step(lin) if len(steps) < MAX_EXTENSIONS and refit is not None else None
        if step is None or refit is None:
            return steps, current, lin
        start = lin.fitted((step.added,)).of(step.added)
        values: dict[str, np.ndarray] = {}
        if current.layout.extensions:
            if current.unknowns is None:
                raise ValueError("the fit carries no estimate of its extensions")
            values = {e: current.unknowns[current.layout.extension_of(e)] for e in current.layout.extensions}
        values[step.added] = np.maximum(start, 0.0) if step.added in NON_NEGATIVE else start
        log.info("diagnosis: adding %s (%s)", step.added, np.round(start, 5))
        after = refit(values, fit.parameters.inertia, None)
        if not np.sum(after.residual_level ** 2) < np.sum(current.residual_level ** 2):
            log.info("diagnosis: with %s the fit is no better: left out", step.added)
            return steps, current, lin
        steps.append(step)
        current = after


def diagnose_rig(rec: Record, prior: Prior, fit: RigFit, cables: list[str],
                 refit: Refit | None = None,
                 damped: DampedStart | None = None, turning: ForcedResponseStart | None = None) -> RigDiagnosis:
    """The data errors and the extensions the recording tells apart (module docstring), and the
    rig model refitted with those added: ``refit`` (:data:`Refit`), given the linearised
    estimates of the extensions' unknowns as their starts (None: no refit).

    rec, prior: the record and prior ``fit`` was made from; cables: the cables' names (rig.yaml).
    Where ``fit`` explains every channel (within
    :data:`~rig_identification.estimation.rig_fit.LEVEL_LIMIT` of its noise) but does not
    determine the tensor (:attr:`~rig_identification.estimation.rig_fit.RigFit.determined`:
    verdict ``not_identifiable``), no extension is tested: the estimate is one of many along the
    tensor's undetermined directions, and the tests at it name physics that is not there
    (bench_trust's clean, undetermined 7201 took ``sensor_delay``); the data errors and the
    gyro's bias are read as ever, and the model's own damping (its alternatives in its place,
    :func:`damping_alternatives`: its σ holds the undetermined directions) where no other minimum
    fits as well (none :attr:`~rig_identification.estimation.rig_fit.RigFit.ambiguous`: at another
    minimum the damping may make up for the tensor's error, as on bench_any_rig's clean 21039,
    Ixx 24 % off and the viscous damping "found").  Under a misfit the tests run
    (σ is not calibrated there, so it does not judge the tensor undetermined).  Where they added
    extensions and the fit with them leaves the tensor undetermined, the rigid-body model is
    fitted again from that fit's tensor, and so it is where the first rigid-body fit had not found
    the motion (:func:`lost`) and an added extension is not determined at the refit
    (:func:`evidenced`: the refit found the motion from its fresh start, not through the
    extension): where it then
    explains every channel, the misfit was its descent's (a flat likelihood holds other minima),
    not the extensions' physics; nothing is named, and that rigid fit is the one reported (on
    bench_trust's clean, undetermined 7201 the first rigid fit misfit and ``sensor_delay`` was
    named; on bench_any_rig's clean, determined 21138 the first rigid fit lost the motion and the
    refit with ``load_cell_delay``, from a fresh start, found it).  Where the rigid-body fit does
    not find the motion and the extensions its tests added do not explain the recording (a channel beyond
    :data:`~rig_identification.estimation.rig_fit.LEVEL_LIMIT` of its noise, or the motion still
    lost), the extensions the recording itself gives a start (:func:`physical_starts`; ``damped``:
    the forced response fitted with the body's damping, the air drag's start; ``turning``: with the
    exciter rotor's unbalance, the rotor's) are fitted from it (:func:`restart_step`), the steps
    go on from the first that finds it, and of the two the fit whose worst channel is nearer its
    noise is kept (at a lost rigid fit the tests' linearisation is no evidence: on bench_trust's
    air-drag rig 8500 it added the exciter's delay, which left the tensions 8–9× their noise).
    """
    if not fit.determined and np.max(fit.residual_level) <= LEVEL_LIMIT:
        # where another minimum fits as well (ambiguous) the damping may make up for the tensor's error
        damping = None if fit.ambiguous else damping_alternatives(LinearisedRig(rec, prior, fit, DAMPING[1:]), fit)
        return RigDiagnosis(prior_conflicts(fit, prior, cables), damping, (), fit, None, False)
    steps, current, lin = _extended(rec, prior, [], fit, refit)
    if steps and lost(current):
        log.info("diagnosis: with %s the fit still does not find the motion: nothing named",
                 ", ".join(s.added for s in steps))
        steps, current = [], fit
    if refit is not None and lost(fit) and (not steps or np.max(current.residual_level) > LEVEL_LIMIT):
        restarted = restart_step(rec, prior, fit, refit, damped, turning)
        if restarted is not None:
            after = _extended(rec, prior, [restarted[0]], restarted[1], refit)
            if not steps or np.max(after[1].residual_level) < np.max(current.residual_level):
                steps, current, lin = after
            else:
                log.info("diagnosis: the fit from %s explains less than the one with %s", restarted[0].added,
                         ", ".join(s.added for s in steps))
    undetermined = not current.determined or (lost(fit) and not evidenced(current, steps))
    if steps and undetermined and refit is not None:
        log.info("diagnosis: the fit with %s leaves the tensor undetermined, or found the motion the first rigid-body "
                 "fit lost with an extension it does not determine: the rigid-body model fitted again from its "
                 "tensor", ", ".join(s.added for s in steps))
        again = refit({}, current.parameters.inertia, None)
        if np.max(again.residual_level) <= LEVEL_LIMIT:
            log.info("diagnosis: the rigid-body model from the tensor of the fit with %s explains every channel "
                     "(the tensor undetermined, or the first rigid-body fit lost and an extension not determined "
                     "at the refit): nothing named", ", ".join(s.added for s in steps))
            return RigDiagnosis(prior_conflicts(again, prior, cables), None, (), again, None, False)
    # where the fit has not found the motion, the estimate is no minimum: a test there is no evidence
    damping = None if lost(current) else damping_alternatives(lin, current)
    conflicts = prior_conflicts(current, prior, cables)
    log.info("diagnosis: data errors %s; extensions %s", [c.unknown for c in conflicts], [s.added for s in steps])
    measured = measured_values(rec, prior, current) if steps else {}
    steps = [replace(s, measured=measured[s.added]) if s.added in measured else s for s in steps]
    return RigDiagnosis(conflicts, damping, tuple(steps), fit, current if steps else None)


__all__ = ["Candidate", "Step", "Damping", "GyroBias", "PriorConflict", "RigDiagnosis", "plausible", "prior_conflicts",
           "gyro_bias", "next_step", "evidenced", "lost", "Refit", "PhysicalStart", "physical_starts", "restart_step",
           "damping_alternatives", "diagnose_rig", "SIGNIFICANCE", "DETERMINED_Z", "APART_LEVEL", "MAX_EXTENSIONS",
           "CONFLICT_SIGMA", "CONFIRM_SHARE", "MEASURED", "confirms", "measured_values", "DAMPING_SIGMA", "BOUNDS",
           "NON_NEGATIVE", "DAMPING", "APART_ADVICE", "PAIR_ADVICE", "apart_advice", "GYRO_CHANNELS"]
