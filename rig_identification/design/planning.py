"""Know before you shake: the experiment design search — which exciter run(s) to do on a rig.

Every σ here is the rig model's (:mod:`~rig_identification.design.information`: every sensor an
output, the fit's nuisance model): the fast screen ranks hundreds of candidate runs by the
linearised rig's Fisher information (:mod:`~rig_identification.design.screen`), and the best few,
simulated by the rig model's own integrator (:func:`~rig_identification.design.information.simulate_run`),
by the exact model's Cramér–Rao bound along the simulation, which is what
``rig-identify inertia`` reaches on a recording of the run.  The linearised rig misses what the
exact model draws from the motion's second-order terms (on the package's default rig the screen's
σ of Izz is 0.2–5× the exact bound, candidate by candidate), so the screen only shortlists:
``refine`` runs are simulated and the choice is made on the exact bound.  The planned run and the
nominal body are :mod:`rig_identification.design.run`'s (the names users import from here are
re-exported).

Design
------
:func:`plan_experiment` searches the exciter frequency, mounting point (corners of the box
spanned by the body anchors and the rig's exciter position), spin axis (body x, y, z or a
diagonal between two of them, :data:`~rig_identification.design.run.SPIN_AXES`), sense of rotation and force
amplitude: the screen of the linearised rig driven from rest by the spinning-up force, then
simulations of the best candidates with the exact model; the amplitude is the largest for
which the simulated run keeps every cable above ``min_tension_ratio`` of its static tension,
the rotation (start-up included) below ``max_rotation_deg``, the force below ``max_force``
and the swing from growing.  Frequencies near a mode, its double or a sum of two modes are
skipped (:func:`resonances`).  A second run — complementary, or the same again — is added when
allowed (the runs fitted at once share the body's unknowns: their information adds,
:func:`~rig_identification.design.information.combined`); it may also use another cable geometry
(``geometries``: the lab's own, or :func:`geometry_variants`, the ceiling anchors moved), which
changes the modes and so the directions the rig moves in.  Pairs are ranked on short simulations
and the best few confirmed by full-length ones before one is chosen.  Objective: ``"baseline"``
(the least-improved entry as much better than a baseline run as possible) or ``"relative"`` (the
largest σ relative to the entry: diagonals to themselves, products to the largest diagonal).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..estimation.directions import describe_direction, weak_directions
from ..estimation.rig_record import RigFitError
from ..io.rig import Rig
from ..io.verdict import KEYS
from ..model.cables import CableModel
from ..model.equilibrium import equilibrium
from ..model.modes import natural_modes
from ..model.parametrisation import entry_scales, from_tensor
from ..model.rigid_body import SimulationError
from .information import (
    BODY,
    RunInformation,
    SimulatedRun,
    body_prior,
    combined,
    covariances,
    run_information,
    simulate_run,
    tensor_std,
)
from .run import SPIN_AXES, Body, PlanError, Run, load_plan_input, make_body
from .screen import RigScreen

# the public names, with those of design.run that users import from here
__all__ = ["SPIN_AXES", "Body", "Candidate", "Plan", "PlanError", "PlanOptions", "Run", "amplitude_at_limits",
           "candidate_positions", "geometry_variants", "load_plan_input", "make_body", "plan_experiment", "resonances"]


def summary(runs: list[RunInformation], prior: np.ndarray, inertia: np.ndarray) -> dict[str, Any]:
    """The σ of the tensor entries from ``runs`` together (the rig model's, :func:`~.information.combined`
    with the body's ``prior``) as the plan's JSON gives it: ``std`` and ``relative_std`` per entry (of
    the entry for moments, of the largest moment for products), ``max_relative_std``,
    ``weakly_determined`` (the two weakest combinations in words,
    :func:`~rig_identification.estimation.directions.describe_direction`),
    ``seconds`` (the fitted spans, summed)."""
    cov = combined(runs, prior)[:6, :6]
    std = np.sqrt(np.abs(np.diag(cov)))
    rel = std / entry_scales(from_tensor(inertia))
    scale = float(np.trace(inertia)) / 3
    weak = [describe_direction(r, D, scale=scale, weakest=i == 0)
            for i, (r, D) in enumerate(weak_directions(inertia, cov, 2))]
    return {"std": {k: float(v) for k, v in zip(KEYS, std)}, "relative_std": {k: float(v) for k, v in zip(KEYS, rel)},
            "max_relative_std": float(np.max(rel)), "weakly_determined": weak,
            "seconds": float(sum(r.seconds for r in runs))}


@dataclass(frozen=True)
class Candidate:
    """A run of the search: the run, what it tells the rig model (:class:`~.information.RunInformation`:
    the screen's, or the exact model's along a simulation; None where a simulation gave the rig model
    nothing to fit), the limit that binds its amplitude, whether it was simulated, its peak rotation
    deg and lowest tension over static, whether its swing keeps growing, the cable geometry
    (None: the rig's own; else the other geometry's label) and the body on it (None: the plan's)."""

    run: Run
    information: RunInformation | None
    limit: str
    simulated: bool = False
    peak_rotation_deg: float | None = None
    min_tension_ratio: float | None = None
    geometry: str | None = None
    body: Body | None = None
    growing: bool = False

    def to_dict(self, prior: np.ndarray, inertia: np.ndarray) -> dict[str, Any]:
        """The run, its geometry, limits and σ alone (:func:`summary`) as the plan's JSON gives them."""
        geo = None
        if self.geometry is not None and self.body is not None:
            geo = {"label": self.geometry,
                   "cables": [{"name": c.name, "ceiling_anchor": [float(x) for x in c.ceiling_anchor],
                               "body_anchor": [float(x) for x in c.body_anchor], "length": float(c.length)}
                              for c in self.body.rig.cables]}
        return {"run": self.run.to_dict(), "cable_geometry": geo, "limit": self.limit, "simulated": self.simulated,
                "peak_rotation_deg": self.peak_rotation_deg, "min_tension_ratio": self.min_tension_ratio,
                "prediction": None if self.information is None else summary([self.information], prior, inertia)}


@dataclass(frozen=True)
class Plan:
    """The recommended runs, the rig model's σ of them together (``std``, (6,) kg·m², and its
    ``covariance`` of the body's ten unknowns) and of the baseline (``baseline_std``), the
    baseline, the rig's modes, the limits used, notes, and each other cable geometry's best
    second run."""

    runs: list[Candidate]
    std: np.ndarray
    covariance: np.ndarray
    baseline: Candidate
    baseline_std: np.ndarray
    modes: list
    limits: dict
    prior: np.ndarray
    inertia: np.ndarray
    notes: list[str] = field(default_factory=list)
    other_geometries: list = field(default_factory=list)

    def improvement(self) -> np.ndarray:
        """(6,) baseline σ / plan σ per entry."""
        return np.asarray(self.baseline_std / self.std)

    def to_dict(self) -> dict[str, Any]:
        runs = [c.information for c in self.runs if c.information is not None]
        return {"modes": [m.to_dict() for m in self.modes],
                "runs": [c.to_dict(self.prior, self.inertia) for c in self.runs],
                "prediction": summary(runs, self.prior, self.inertia),
                "baseline": self.baseline.to_dict(self.prior, self.inertia),
                "improvement": {k: float(v) for k, v in zip(KEYS, self.improvement())},
                "limits": dict(self.limits), "notes": list(self.notes),
                "other_geometries": [c.to_dict(self.prior, self.inertia) for c in self.other_geometries]}


def candidate_positions(rig: Rig) -> list[np.ndarray]:
    """Mounting points: the corners of the box spanned by the body anchors and the rig's
    exciter position (body frame, m); a flat box (all anchors at one height, no exciter)
    keeps its two faces at the anchors' height and at the CG's."""
    pts = [*rig.body_anchors]
    if rig.exciter is not None:
        pts.append(rig.exciter.position)
    pts.append(rig.require_cg())
    box = np.array(pts)
    lo, hi = box.min(0), box.max(0)
    return [np.array([x, y, z]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]


#: Times :func:`_fit_amplitude` rescales a run's force and simulates it again, at most.
AMPLITUDE_TRIES = 2


def _sim_check(body: Body, run: Run) -> tuple[Candidate, SimulatedRun]:
    """Simulate ``run`` without noise (:func:`~.information.simulate_run`): its peak rotation,
    lowest tension ratio and whether the swing keeps growing.  Returns (the candidate, without
    its information yet, and the simulation)."""
    sim = simulate_run(body, run)
    return Candidate(run, None, "", True, sim.peak_rotation_deg, sim.min_tension_ratio, growing=sim.growing), sim


def _informed(c: Candidate, sim: SimulatedRun) -> Candidate:
    """``c`` with what its simulation ``sim`` tells the rig model (:func:`~.information.run_information`;
    None where slack cables leave it nothing to fit)."""
    try:
        return replace(c, information=run_information(sim))
    except (RigFitError, SimulationError, np.linalg.LinAlgError):
        return c


def _within(c: Candidate, limits: dict) -> bool:
    return (c.peak_rotation_deg is not None and c.min_tension_ratio is not None
            and c.peak_rotation_deg <= limits["max_rotation_deg"] * 1.001
            and c.min_tension_ratio >= limits["min_tension_ratio"] * 0.999 and not c.growing
            and c.run.amplitude <= limits["max_force_n"] * 1.001)


def _fit_amplitude(body: Body, run: Run, limits: dict, grow: bool = True, say=None,
                   informed: bool = True) -> Candidate | None:
    """Simulate ``run`` and bring its force amplitude to the limits: scale it linearly so
    that the simulated peak rotation and lowest tension (start-up transients and beats
    included) meet them with a 3 % margin, at most ``limits["max_force_n"]`` (up only if
    ``grow``), and simulate again (announced to ``say``, callable(str), when given), at most
    :data:`AMPLITUDE_TRIES` times; then, where ``informed``, what the last simulation tells the
    rig model (:func:`_informed`).  None if the run still breaks a limit, its swing keeps
    growing (a parametric resonance) or it leaves the rig model nothing to fit."""
    cand, sim = _sim_check(body, run)
    for _ in range(AMPLITUDE_TRIES):
        if cand.growing:
            return None
        assert cand.peak_rotation_deg is not None and cand.min_tension_ratio is not None
        s_rot = np.radians(limits["max_rotation_deg"]) / max(np.radians(cand.peak_rotation_deg), 1e-12)
        s_ten = (1 - limits["min_tension_ratio"]) / max(1 - cand.min_tension_ratio, 1e-12)
        s_force = limits["max_force_n"] / run.amplitude
        s = min(s_rot, s_ten)
        if s >= 1.0:
            s = 0.97 * s if grow else 1.0
            if s < 1.05 and s_force >= 1.0:
                break
            s = min(s, s_force)         # a force beyond the exciter's is brought down to it
        else:
            s = min(0.97 * s, s_force)
        if s == 1.0:                    # at the force limit already: the same run again would change nothing
            break
        run = replace(run, amplitude=run.amplitude * s)
        if say is not None:
            say(f"simulating it again at {run.amplitude:.0f} N (its amplitude brought to the limits) ...")
        cand, sim = _sim_check(body, run)
        grow = False
    if not _within(cand, limits):
        return None
    if informed:
        cand = _informed(cand, sim)
        if cand.information is None:
            return None
    assert cand.peak_rotation_deg is not None and cand.min_tension_ratio is not None
    use = {"rotation": cand.peak_rotation_deg / limits["max_rotation_deg"],
           "tension": (1 - cand.min_tension_ratio) / (1 - limits["min_tension_ratio"]),
           "force": run.amplitude / limits["max_force_n"]}
    return replace(cand, limit=max(use, key=lambda k: use[k]))   # the limit it comes closest to


def amplitude_at_limits(body: Body, run: Run, max_rotation_deg: float = 3.0, min_tension_ratio: float = 0.2,
                        max_force: float = math.inf) -> Candidate | None:
    """``run`` (its frequency, exciter position and spin axis kept) at the largest force
    amplitude within the limits of :func:`plan_experiment` (same defaults): peak rotation ≤
    ``max_rotation_deg``, every cable ≥ ``min_tension_ratio`` × its static tension (start-up
    and beats included, 3 % margin), force ≤ ``max_force`` N; found by noise-free
    simulation as the planner does (:func:`_fit_amplitude`).  Returns the
    :class:`Candidate` (``.run.amplitude`` N, ``.peak_rotation_deg``,
    ``.min_tension_ratio``, ``.information``), or None if no amplitude keeps the run within
    the limits (its swing keeps growing).  Raises :class:`PlanError` for bad limits,
    :class:`~rig_identification.model.rigid_body.SimulationError`."""
    return _fit_amplitude(body, run, _limits(max_force, max_rotation_deg, min_tension_ratio))


def _limits(max_force: float, max_rotation_deg: float, min_tension_ratio: float) -> dict:
    """The run limits of :func:`plan_experiment` as a mapping.  Raises :class:`PlanError`."""
    if not (0 <= min_tension_ratio < 1) or not max_rotation_deg > 0 or not max_force > 0:
        raise PlanError("limits: need 0 ≤ min tension ratio < 1, max rotation > 0, max force > 0")
    return {"max_force_n": max_force, "max_rotation_deg": max_rotation_deg, "min_tension_ratio": min_tension_ratio}


@dataclass(frozen=True)
class PlanOptions:
    """What :func:`plan_experiment` searches and within which limits.

    duration: s of each run.  Limits: force amplitude ≤ ``max_force`` N, body rotation ≤
    ``max_rotation_deg`` (peak, start-up included), every cable ≥ ``min_tension_ratio`` × its
    static tension, no growing swing; exciter frequencies in ``frequencies`` Hz and at least
    ``mode_margin`` (relative) away from every natural frequency, its double and every pairwise
    sum (:func:`resonances`).  positions: candidate mounting points (body m; default
    :func:`candidate_positions`).  max_runs: 1 or 2.  objective: ``"baseline"`` — make the
    least-improved entry as much better than the baseline as possible (minimise
    max_k σ_k / σ_k,baseline), or ``"relative"`` — minimise the largest relative σ (diagonals
    relative to themselves, products to the largest diagonal).  refine: how many screened
    candidates are simulated (``short`` s each).  settle: s the screen leaves out at the start
    (the spin-up).  geometries: other cable geometries the rig can take for the second run, [(label,
    :class:`~rig_identification.io.rig.Rig`)] with the same body (e.g. :func:`geometry_variants`);
    the best runs on each are searched like the rig's own and paired with the best run on the rig."""

    duration: float = 120.0
    max_force: float = math.inf
    max_rotation_deg: float = 3.0
    min_tension_ratio: float = 0.2
    frequencies: tuple[float, float] = (0.3, 4.0)
    positions: tuple | None = None
    max_runs: int = 2
    objective: str = "baseline"
    refine: int = 3
    settle: float = 5.0
    short: float = 30.0
    mode_margin: float = 0.1
    geometries: tuple = ()


#: Frequencies screened per progress line of :func:`plan_experiment`.
SCREEN_GROUP = 4
#: The most exciter frequencies the search screens, and the least ratio between two of them.
SCREEN_FREQUENCIES = 30
SCREEN_FREQUENCY_RATIO = 1.02


def screened_frequencies(band: tuple[float, float]) -> np.ndarray:
    """The exciter frequencies (Hz) the search screens in ``band`` (low, high): evenly spaced in
    log, at most :data:`SCREEN_FREQUENCIES` and at least :data:`SCREEN_FREQUENCY_RATIO` apart."""
    lo, hi = band
    n = int(np.ceil(np.log(hi / lo) / np.log(SCREEN_FREQUENCY_RATIO))) + 1
    out: np.ndarray = np.geomspace(lo, hi, max(2, min(SCREEN_FREQUENCIES, n)))
    return out


class _Search:
    """One plan's search (:func:`plan_experiment`): the limits, the reference σ the runs are
    ranked against, and the short and full-length simulations made so far (each run once)."""

    def __init__(self, body: Body, opts: PlanOptions, limits: dict, say, ref_screen: np.ndarray,
                 ref_sim: np.ndarray):
        self.body, self.opts, self.limits, self.say = body, opts, limits, say
        self.ref_screen, self.ref_sim = ref_screen, ref_sim
        self.prior = body_prior(body.rig)
        self.short = min(opts.short, opts.duration)
        self.done: dict = {}
        self.full: dict = {}

    def worst(self, *cs: Candidate, ref: np.ndarray | None = None) -> float:
        """The worst entry's σ over the reference (the simulations' unless ``ref``) of ``cs`` done together."""
        infos = [c.information for c in cs if c.information is not None]
        if len(infos) < len(cs):
            return math.inf
        return float(np.max(tensor_std(infos, self.prior) / (self.ref_sim if ref is None else ref)))

    def search(self, b: Body, label: str | None, modes, scr: RigScreen | None = None,
               partner: Candidate | None = None) -> tuple[list[Candidate], list[Candidate]]:
        """Screen frequencies, mounting points and spin axes on the body ``b`` (cable
        geometry ``label``; None: the rig's own, whose ``modes`` are given), then simulate the
        best distinct ``refine`` of them (``short`` s, amplitude brought to the limits): best
        alone and, with ``partner`` given, also best together with that run (a second run).
        Returns (screened, simulated singles)."""
        o = self.opts
        where = "" if label is None else f" ({label})"
        ms = modes if label is None else natural_modes(b.rig, b.mass, b.rig.require_cg(), b.inertia, b.stiffness)
        mf = np.array([m.frequency for m in ms])
        scr = scr or RigScreen(b, o.duration, o.settle)
        avoid = resonances(mf)
        freqs = [f for f in screened_frequencies(o.frequencies) if np.all(np.abs(f / avoid - 1) >= o.mode_margin)]
        if not freqs:
            raise PlanError(f"no exciter frequency in {o.frequencies[0]:g}–{o.frequencies[1]:g} Hz is "
                            f"{100 * o.mode_margin:.0f} % "
                            f"away from the rig's modes{where} ({', '.join(f'{f:.2f}' for f in mf)} Hz), their doubles "
                            "and their pairwise sums")
        pts = [np.asarray(p, float) for p in (o.positions if o.positions else candidate_positions(b.rig))]
        screened: list[Candidate] = []
        for i in range(0, len(freqs), SCREEN_GROUP):
            group = freqs[i:i + SCREEN_GROUP]
            self.say(f"screening {group[0]:.2f}–{group[-1]:.2f} Hz (frequencies {i + 1}–{i + len(group)} of "
                     f"{len(freqs)}; at each {len(pts)} mounting points × {len(SPIN_AXES)} spin axes × 2 senses, "
                     f"linearised rig{where}) ...")
            for f in group:
                screened += self._screen_frequency(scr, b, label, f, pts)
        screened.sort(key=lambda c: self.worst(c, ref=self.ref_screen))
        picks = _distinct(screened, o.refine)
        if partner is not None:   # a ranking only: the partner's information is simulated, the candidates' screened
            together = sorted(screened, key=lambda c: self.worst(partner, c))
            picks += [c for c in _distinct(together, o.refine) if all(not _same(c, o_) for o_ in picks)]
        singles = [x for x in (self.simulate_short(c, "a candidate run") for c in picks) if x is not None]
        return screened, singles

    def _screen_frequency(self, scr: RigScreen, b: Body, label: str | None, f: float,
                          pts: list[np.ndarray]) -> list[Candidate]:
        """The screened candidates at ``f`` Hz on the body ``b`` (cable geometry ``label``): every
        mounting point of ``pts`` (body m), spin axis and sense that determines the tensor."""
        at = scr.at(f)
        out = []
        for p in pts:
            for ax in SPIN_AXES:
                for sense in (1, -1):
                    sr = at.candidate(p, SPIN_AXES[ax], self.limits, direction=sense)
                    if not np.all(np.isfinite(tensor_std([sr.information], self.prior))):
                        continue
                    out.append(Candidate(Run(float(f), sr.amplitude, tuple(float(x) for x in p), ax,
                                             self.opts.duration, direction=sense), sr.information, sr.limit, False,
                                         sr.rotation_deg, sr.min_tension_ratio, geometry=label, body=b))
        return out

    def simulate_short(self, c: Candidate, what: str) -> Candidate | None:
        """``c`` simulated over ``short`` s, its amplitude brought to the limits, its information
        scaled to the full length; None if it breaks a limit."""
        key = _run_key(c)
        if key not in self.done:
            o = self.opts
            where = "" if c.geometry is None else f" ({c.geometry})"
            sense = "" if c.run.direction > 0 else " (reversed)"
            self.say(f"simulating {what}{where}: {c.run.frequency:.2f} Hz, {c.run.amplitude:.0f} N, spin axis "
                     f"{c.run.spin_axis}{sense}, at {np.round(c.run.position, 2).tolist()} m ({self.short:.0f} s) ...")
            cs = _fit_amplitude(c.body or self.body, replace(c.run, duration=self.short), self.limits)
            if cs is not None and cs.information is not None:
                info = cs.information
                cs = replace(cs, information=info.scaled(info.seconds + o.duration - self.short),
                             geometry=c.geometry, body=c.body)
            self.done[key] = cs
        return self.done[key]

    def simulate_full(self, c: Candidate, what: str) -> Candidate | None:
        """``c`` simulated over the whole ``duration``, its amplitude brought to the limits
        again (a run can break a limit late: beats, slow growth).  None if it cannot."""
        key = _run_key(c)
        if key not in self.full:
            o = self.opts
            if self.short >= o.duration:   # already simulated in full
                self.full[key] = c
                return c
            where = "" if c.geometry is None else f" on cable geometry {c.geometry!r}"
            self.say(f"simulating {what}{where} in full ({c.run.amplitude:.0f} N at {c.run.frequency:.2f} Hz, "
                     f"{o.duration:.0f} s; the rig model's bound along it) ...")
            cf = _fit_amplitude(c.body or self.body, replace(c.run, duration=o.duration), self.limits, say=self.say)
            if cf is not None:
                cf = replace(cf, geometry=c.geometry, body=c.body)
            self.full[key] = cf
        return self.full[key]


def _checked_limits(opts: PlanOptions) -> dict:
    """The run limits and the search's settings as the plan reports them.  Raises :class:`PlanError`."""
    limits = _limits(opts.max_force, opts.max_rotation_deg, opts.min_tension_ratio)
    if not 0 < opts.frequencies[0] < opts.frequencies[1]:
        raise PlanError(f"frequency range {opts.frequencies} Hz must be 0 < low < high")
    if opts.objective not in ("baseline", "relative"):
        raise PlanError(f"objective {opts.objective!r}: baseline or relative")
    if not opts.duration > opts.settle + 10.0:
        raise PlanError(f"--duration {opts.duration:g} s: runs must last more than {opts.settle + 10:g} s")
    limits.update({"duration_s": opts.duration, "frequency_range_hz": list(opts.frequencies),
                   "mode_margin": opts.mode_margin, "objective": opts.objective})
    return limits


def _baseline(body: Body, baseline: Run, opts: PlanOptions, limits: dict, screen: RigScreen,
              say) -> tuple[Candidate, np.ndarray, np.ndarray]:
    """The baseline simulated in full and screened (each stage compares like with like):
    (its candidate, the reference σ of the screen's ranking, that of the simulations')."""
    say(f"simulating the baseline ({baseline.amplitude:.0f} N at {baseline.frequency:.2f} Hz, "
        f"{opts.duration:.0f} s; the rig model's bound along it) ...")
    base, sim = _sim_check(body, replace(baseline, duration=opts.duration))
    base = replace(_informed(base, sim), limit="baseline")
    prior = body_prior(body.rig)
    if base.information is None or not np.all(np.isfinite(tensor_std([base.information], prior))):
        raise PlanError(f"the baseline excitation ({baseline.amplitude:g} N at {baseline.frequency:g} Hz) slackens "
                        "cables or moves the body so little that the rig model could not fit it; choose another "
                        "--baseline-force or --baseline-frequency")
    if opts.objective == "relative":
        scale = entry_scales(from_tensor(body.inertia))
        return base, scale, scale
    screened = screen.at(baseline.frequency).candidate(baseline.position, baseline.exciter_rpy, limits,
                                                       baseline.amplitude)
    ref_screen = tensor_std([screened.information], prior)
    ref_sim = tensor_std([base.information], prior)
    return base, (ref_screen if np.all(np.isfinite(ref_screen)) else ref_sim), ref_sim


def _first_run(s: _Search, singles: list[Candidate]) -> Candidate:
    """The best single run, confirmed in full (falling back on the next if it breaks a limit late)."""
    for n_c, c in enumerate(singles):
        first = s.simulate_full(c, "the best run" if n_c == 0 else "the next candidate")
        if first is not None:
            return first
    raise PlanError(f"every candidate run broke a limit over {s.opts.duration:.0f} s in simulation (cable slack, "
                    "rotation, growing swing); lower --max-force or change the frequency range")


def _second_run(s: _Search, first: Candidate, singles: list[Candidate], screened: list[Candidate], modes
                ) -> tuple[list[Candidate], list[str], list[Candidate]]:
    """The second run: a complementary one (on the rig's geometry or another of ``geometries``)
    or the first again.  Returns (the chosen runs, notes, each other geometry's best second run)."""
    body, rig, o = s.body, s.body.rig, s.opts
    notes: list[str] = []
    others: list[Candidate] = []
    sims2 = []
    for a, b in _best_pairs(screened, max(2, o.refine // 2), s.ref_screen, s.prior):
        sa, sb = s.simulate_short(a, "a pair, first run"), s.simulate_short(b, "a pair, second run")
        if sa is not None and sb is not None:
            sims2.append((sa, sb))
    sims2 += [(x, y) for k, x in enumerate(singles) for y in singles[k + 1:]]
    g_best: dict = {}
    for label, grig in o.geometries:
        if len(grig.cables) != len(rig.cables):
            notes.append(f"cable geometry {label!r} not usable: {len(grig.cables)} cables, the rig has "
                         f"{len(rig.cables)}")
            continue
        try:
            gb = replace(body, rig=replace(grig, mass=body.mass, center_of_gravity=rig.require_cg()))
            _, gs = s.search(gb, label, modes, partner=singles[0])
        except (PlanError, SimulationError) as e:
            notes.append(f"cable geometry {label!r} not usable: {e}")
            continue
        if not gs:
            notes.append(f"cable geometry {label!r}: every candidate run broke a limit in simulation")
        sims2 += [(singles[0], y) for y in gs]
        if gs:
            g_best[label] = min(gs, key=lambda y: s.worst(singles[0], y))
    # the short runs' information, scaled to the full length, only ranks the pairs (beats and
    # start-up weigh differently in 30 s): the best few that promise to beat the best run done
    # twice are simulated in full and compared in full
    repeat_short = s.worst(singles[0], singles[0])
    promising = [ab for ab in sorted(sims2, key=lambda ab: s.worst(*ab)) if s.worst(*ab) < repeat_short][:3]
    repeat = s.worst(first, first)
    best, best_val = None, repeat
    for a, b in promising:
        fa, fb = s.simulate_full(a, "a pair's first run"), s.simulate_full(b, "a pair's second run")
        if fa is not None and fb is not None and s.worst(fa, fb) < best_val:
            best, best_val = (fa, fb), s.worst(fa, fb)
        # a run simulated in full for a pair may itself be the better run to do twice than the best screened single
        for f in (fa, fb):
            if f is not None and s.worst(f, f) < best_val:
                best, best_val = (f, f), s.worst(f, f)
    if best is not None and best[0] is best[1]:
        chosen = list(best)
        notes.append(f"a run simulated as part of a pair, done twice: worst entry σ/reference {best_val:.3g}, "
                     f"against {repeat:.3g} for the best screened run done twice")
    elif best is not None:
        chosen = list(best)
        other = "" if best[1].geometry is None else f" (the second on cable geometry {best[1].geometry!r})"
        notes.append(f"two complementary runs{other}: worst entry σ/reference {best_val:.3g}, against "
                     f"{repeat:.3g} for the best run done twice and {s.worst(first):.3g} for it alone")
    else:
        chosen = [first, first]
        notes.append(f"no other run complements the best one better than itself: do it twice (worst entry "
                     f"σ/reference {repeat:.3g} against {s.worst(first):.3g} for one run)")
    for label, y in g_best.items():   # what each other geometry offered (full-length where simulated so)
        key = _run_key(y)
        yf = s.full.get(key)
        others.append(yf if yf is not None else y)
        how = ("full-length simulation" if yf is not None else
               "short simulation; it broke a limit over the full length" if key in s.full else "short simulation")
        notes.append(f"cable geometry {label!r}: its best second run, {others[-1].run.amplitude:.0f} N at "
                     f"{others[-1].run.frequency:.2f} Hz, gives worst entry σ/reference "
                     f"{s.worst(first, others[-1]):.3g} with the best run ({how})")
    return chosen, notes, others


def plan_experiment(body: Body, baseline: Run, options: PlanOptions = PlanOptions(), progress=None) -> Plan:
    """Recommend one or two exciter runs (see module docstring).

    body: :class:`Body`.  baseline: the run to compare with (e.g. the thesis's 200 N at
    1.05 Hz at the rig's exciter).  options: :class:`PlanOptions` (limits, search, objective).
    progress: optional callable(str), called as each step starts: each group of
    :data:`SCREEN_GROUP` frequencies screened, each simulation.
    Raises :class:`PlanError`, :class:`~rig_identification.model.rigid_body.SimulationError`.
    """
    say = progress or (lambda s: None)
    limits = _checked_limits(options)
    rig = body.rig
    modes = natural_modes(rig, body.mass, rig.require_cg(), body.inertia, body.stiffness)
    screen = RigScreen(body, options.duration, options.settle)
    base, ref_screen, ref_sim = _baseline(body, baseline, options, limits, screen, say)
    s = _Search(body, options, limits, say, ref_screen, ref_sim)
    screened, singles = s.search(body, None, modes, screen)
    if not screened:
        raise PlanError("no candidate run moves the body enough to determine the tensor")
    if not singles:
        raise PlanError("every screened candidate broke a limit in simulation (cable slack, rotation, growing "
                        "swing): lower --max-force or change the frequency range")
    singles.sort(key=s.worst)
    first = _first_run(s, singles)
    chosen: list[Candidate] = [first]
    notes: list[str] = []
    others: list[Candidate] = []
    if options.max_runs >= 2:
        chosen, notes, others = _second_run(s, first, singles, screened, modes)
    infos = [c.information for c in chosen if c.information is not None]
    assert base.information is not None
    cov = combined(infos, s.prior)
    return Plan(chosen, np.sqrt(np.abs(np.diag(cov)))[:6], cov, base, tensor_std([base.information], s.prior),
                modes, limits, s.prior, body.inertia, notes, others)


def geometry_variants(body: Body, shift: float = 1.0) -> list[tuple[str, Rig]]:
    """Other cable geometries for a second run: the ceiling anchors moved ``shift`` m
    farther apart (and, where they stay more than 0.2 m outside the body anchors, closer
    together) along world x, and along world y — each anchor away from (toward) the
    anchors' mid-point on that axis — with every cable length re-set to the anchors'
    distance at the rig's own equilibrium pose (cables of the same material: the
    stiffness is kept).  The body settles near that pose: the new cable directions
    balance its weight at a slightly different one (on the thesis rig within 5 cm and
    3°).  A variant whose cables would lean inward is left out.  Returns [(label, Rig)]."""
    rig = body.rig
    cm = CableModel.spring(rig, body.mass, stiffness=body.stiffness)
    pos, R0, _ = equilibrium(rig, body.mass, rig.require_cg(), cm)
    B = pos + R0.apply(rig.body_anchors)                     # body anchors in world at equilibrium
    A = np.asarray(rig.ceiling_anchors, float)
    out = []
    for ax, name in ((0, "x"), (1, "y")):
        mid = 0.5 * (A[:, ax].min() + A[:, ax].max())
        side = np.sign(A[:, ax] - mid)
        for sense, word in ((1, "farther apart"), (-1, "closer together")):
            A2 = A.copy()
            A2[:, ax] += sense * shift * side
            if sense < 0 and np.any(side * (A2[:, ax] - B[:, ax]) < 0.2):
                continue        # the cables would lean inward: another rig, not a variant
            L = np.linalg.norm(A2 - B, axis=1)
            cables = tuple(replace(c, ceiling_anchor=a, length=float(l)) for c, a, l in zip(rig.cables, A2, L))
            out.append((f"ceiling anchors {shift:g} m {word} along world {name}", replace(rig, cables=cables)))
    return out


def _run_key(c: Candidate) -> tuple:
    """What makes a run distinct for the simulation caches: geometry, frequency, mounting
    point, spin axis and sense (the amplitude is fitted)."""
    return (c.geometry, c.run.frequency, c.run.position, c.run.spin_axis, c.run.direction)


def _best_pairs(cands: list[Candidate], n: int, ref: np.ndarray, prior: np.ndarray
                ) -> list[tuple[Candidate, Candidate]]:
    """The ``n`` best distinct pairs of screened runs fitted at once (their information on the body
    added, the body's ``prior`` once: :func:`~.information.combined`), by the worst entry's σ over ``ref``."""
    B = np.array([c.information.body if c.information is not None else np.zeros((BODY, BODY)) for c in cands])
    i, j = np.triu_indices(len(cands), 1)
    out = np.full(len(i), np.inf)
    for lo in range(0, len(i), 20000):
        sl = slice(lo, lo + 20000)
        var = np.einsum("pkk->pk", covariances(B[i[sl]] + B[j[sl]] + prior))[:, :6]
        out[sl] = np.max(np.sqrt(np.clip(var, 0, None)) / ref, axis=1)
    order = np.argsort(out)
    taken: list[tuple[Candidate, Candidate]] = []
    for k in order:
        if not np.isfinite(out[k]):
            break
        a, b = cands[i[k]], cands[j[k]]
        if all(not (_same(a, x) and _same(b, y)) and not (_same(a, y) and _same(b, x)) for x, y in taken):
            taken.append((a, b))
        if len(taken) >= n:
            break
    return taken


def _same(a: Candidate, b: Candidate) -> bool:
    return (a.run.spin_axis == b.run.spin_axis and a.run.direction == b.run.direction
            and np.allclose(a.run.position, b.run.position) and abs(a.run.frequency / b.run.frequency - 1) < 0.15)


def resonances(mode_f) -> np.ndarray:
    """Frequencies (Hz) an exciter must stay away from: the natural frequencies f_i (primary
    resonance), 2 f_i and f_i + f_j (parametric and combination resonances: the rotating
    force modulates the cables' geometric stiffness; on the thesis rig 2.02 Hz = 0.85 + 1.18 Hz
    makes the swing grow until a cable goes slack, even at 160 N)."""
    f = np.asarray(mode_f, float)
    i, j = np.triu_indices(len(f))
    return np.unique(np.concatenate([f, f[i] + f[j]]))


def _distinct(cands: list[Candidate], n: int) -> list[Candidate]:
    """The first ``n`` candidates that differ in mounting point / spin axis or by ≥ 15 % in
    frequency from the ones already taken."""
    out: list[Candidate] = []
    for c in cands:
        if all(not _same(c, o) for o in out):
            out.append(c)
        if len(out) >= n:
            break
    return out
