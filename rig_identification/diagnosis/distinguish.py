"""Which effects a recording tells apart: rival combinations, the class they share, what would separate them.

Two admissible combinations of effects (each member significant given the others:
:func:`~rig_identification.diagnosis.selection.diagnose`) that explain the recording about
equally well are not told apart by it, whatever their ranking.  The best combination's rivals
(:func:`rivals`) are the admissible combinations that neither contain it nor are contained in it
(nested ones are settled by the members' own likelihood-ratio tests) and whose likelihood-ratio
statistic against the rigid-body model falls short of the best's by less than the bar an effect
must clear to be named at all: the χ² quantile of one degree of freedom at the selection's
Bonferroni level (Λ_best − Λ_rival < χ²₁(1 − p); the recording prefers neither by as much as it
must prefer one parameter over none).  This is the comparison of non-nested models by their
likelihoods, with the selection's own threshold (Vuong 1989, Econometrica 57(2), 307–333, for the
test; Ljung 1999 ch. 16.4 for model-structure selection by the likelihood).

The members of the best combination that are not in every rival are not named: the diagnosis
names their *class* (:data:`CLASSES`) and the candidates it cannot tell apart, keeps the best
combination's member as the model of the misfit (the tensor is still corrected), and says what
recording would tell them apart (:func:`ambiguity`).
"""
from __future__ import annotations

from scipy.stats import chi2

from ..io.export import effect_text
from .candidates import CORRECTIONS

CLASSES = (
    ("velocity-dependent damping", frozenset({"viscous_damping", "air_drag", "coulomb_friction"}),
     "a run at a second forcing amplitude (exciter speed or unbalance): their forces grow differently with "
     "the speed (Coulomb ∝ v⁰, viscous ∝ v, quadratic ∝ v²)"),
    ("a timing error between the streams", frozenset({"sensor_delay"}),
     "a stamped synchronisation pulse on every stream, or the DAQ's and the IMU's clocks compared (only the "
     "streams' relative time is in the recording)"),
    ("an error of the IMU's mounting or calibration",
     frozenset({"imu_offset", "imu_misalignment", "gyro_scale", "gyro_bias", "accelerometer_bias"}),
     "the IMU's pose measured on the body (a survey), or a recording that turns the body about another axis"),
    ("mass or a centre of gravity the rig.yaml does not describe",
     frozenset({"cable_mass", "body_mass", "cg_offset", "exciter_rotor", "load_cell_scale"}),
     "the body weighed, its CG from the static pair (rig-identify cg), the cables' and the exciter's rotor's "
     "masses measured, or a run at a second exciter speed (the rotor's force grows with its square)"),
)
"""(class, its effects, what would tell its members apart): the kinds of physics whose
effects a recording at one operating point often cannot separate.  Effects of different
classes share the generic class :data:`MIXED`."""

MIXED = ("effects of different kinds that explain the same misfit",
         "a recording at another operating point (a second forcing amplitude or exciter speed, another "
         "excitation axis), or the suspected quantities measured")


DATA_ERRORS = frozenset(CORRECTIONS) | {"cable_mass", "cable_elasticity"}
"""Errors of the data or of the rig's description
(:data:`~rig_identification.diagnosis.candidates.CORRECTIONS`, and the cables' mass and stiffness
that rig.yaml leaves out or gets wrong), as opposed to physics the model lacks (damping, drag,
friction, the exciter's rotor, the gyroscopic term): :func:`preferred` models a misfit with them
first."""


def distinguish_bar(threshold_p: float) -> float:
    """The likelihood-ratio margin (2 Δ log-likelihood) by which the best combination must beat a
    rival to be told apart from it: χ²₁ quantile at ``threshold_p`` (the selection's Bonferroni
    level; ``scipy.stats.chi2.isf``)."""
    return float(chi2.isf(threshold_p, 1))


def rivals(ranked: list[dict], threshold_p: float) -> list[dict]:
    """The admissible combinations the recording does not tell apart from the best.

    ranked: :func:`~rig_identification.diagnosis.selection.diagnose`'s admissible
    evaluations, the best (smallest BIC) first; each a dict with ``keys`` (the members'
    (name, label)) and ``lam`` (likelihood-ratio statistic against the rigid-body model).
    Returns those that are neither a superset nor a subset of the best and whose ``lam`` is
    within :func:`distinguish_bar` of the best's (below or above), in ``ranked``'s order."""
    if not ranked:
        return []
    best, bar = ranked[0], distinguish_bar(threshold_p)
    keys = set(best["keys"])
    return [ev for ev in ranked[1:]
            if not (set(ev["keys"]) <= keys or set(ev["keys"]) >= keys) and abs(best["lam"] - ev["lam"]) < bar]


def class_of(names: set[str]) -> tuple[str, str]:
    """(class, what tells its members apart) of the effect names ``names``: the first of
    :data:`CLASSES` that holds them all, else :data:`MIXED`."""
    for label, members, tells in CLASSES:
        if names <= members:
            return label, tells
    return MIXED


def ambiguity(ranked: list[dict], threshold_p: float) -> list[dict]:
    """The best combination's members that the recording does not tell apart from its rivals
    (:func:`rivals`): the members common to the best and every rival are told apart; the rest
    of the best (its members in doubt) and what stands in their place in each rival are one
    class.  Returns [] when the best has no rival, else one entry: ``candidate_keys`` (the best's
    members in doubt, (name, label), then the rivals' members in their place), ``candidates``
    (one text per combination, the best's first: its members in doubt as "name" or "name
    label", joined by " + "), ``class`` and ``tells_apart``
    (:func:`class_of` of every name among them), ``likelihood_ratios`` (the best's Λ and each
    rival's, the rivals' order) and ``bar`` (:func:`distinguish_bar`)."""
    rs = rivals(ranked, threshold_p)
    if not rs:
        return []
    best = ranked[0]
    common = set(best["keys"]).intersection(*(set(r["keys"]) for r in rs))
    groups = [[k for k in ev["keys"] if k not in common] for ev in [best] + rs]
    keys = [k for g in groups for k in g]
    label, tells = class_of({k[0] for k in keys})
    return [{"candidate_keys": list(dict.fromkeys(keys)),
             "candidates": [" + ".join(" ".join(x for x in k if x) for k in g) for g in groups],
             "class": label, "tells_apart": tells,
             "likelihood_ratios": [float(best["lam"])] + [float(r["lam"]) for r in rs],
             "bar": distinguish_bar(threshold_p)}]


def preferred(ranked: list[dict], threshold_p: float) -> list[dict]:
    """``ranked`` with the combination that models the misfit first: among the best and its
    :func:`rivals` (which the recording does not tell apart), data errors before physics (a
    combination of :data:`DATA_ERRORS` only: a sensor or rig error is removed from the data
    before physics is added to the model), then the fewest parameters (``dof``), then the
    smallest BIC; the rest of ``ranked`` after, in its order."""
    if not ranked:
        return []
    group = [ranked[0]] + rivals(ranked, threshold_p)
    physics = lambda ev: any(k[0] not in DATA_ERRORS for k in ev["keys"])  # noqa: E731
    first = min(group, key=lambda ev: (physics(ev), ev["dof"], ev["bic"]))
    return [first] + [ev for ev in ranked if ev is not first]


def effect_name(entry: dict) -> str:
    """What a diagnosis says of an effect entry: its name when the recording told it apart,
    else its class and the candidates ("velocity-dependent damping: viscous_damping or air_drag,
    not told apart")."""
    if entry.get("told_apart", True):
        return str(entry["name"])
    return f"{entry['class']}: {' or '.join(entry['candidates'])}, not told apart"


def finding_text(entry: dict) -> str:
    """An effect entry in one phrase with its parameters and units
    (:func:`~rig_identification.io.export.effect_text`): "name (parameters)", or for an effect
    not told apart "class: candidates, not told apart (modelled as name: parameters) — what would
    tell them apart: …"."""
    if entry.get("told_apart", True):
        return f"{entry['name']} ({effect_text(entry)})"
    return (f"{effect_name(entry)} (modelled as {entry['name']}: {effect_text(entry)}) — what would tell them "
            f"apart: {entry['tells_apart']}")
