"""Know before you shake: the experiment design search — which exciter run(s) to do on a rig.

The σ the plan and the baseline reach with ``rig-identify inertia`` is the rig model's
Cramér–Rao bound (:mod:`~rig_identification.design.information`: every sensor an output, the
fit's nuisance model), computed once the runs are chosen (``Plan.rig_model``).  The search ranks
runs by the gyro-only prediction-error fit's prediction
(:func:`~rig_identification.estimation.propagation.predict_from_trajectory`: fast enough for
hundreds of candidates; larger than the rig model's σ — the load cells see the motion more
finely — but largest for the runs that move the body least).  The planned run and the nominal
body are :mod:`rig_identification.design.run`'s, the linearised screen
:mod:`rig_identification.design.screen`'s (the names users import from here are re-exported).

Design
------
:func:`plan_experiment` searches the exciter frequency, mounting point (corners of the box
spanned by the body anchors and the rig's exciter position), spin axis (body x, y, z or a
diagonal between two of them, :data:`~rig_identification.design.run.SPIN_AXES`), sense of rotation and force
amplitude: a fast screen of the linearised rig (:func:`~rig_identification.design.screen.linear_rig`)
driven from rest by the spinning-up force and the stationary form of the noise model, then
simulations of the best candidates with the full predictor; the amplitude is the largest for
which the simulated run keeps every cable above ``min_tension_ratio`` of its static tension,
the rotation (start-up included) below ``max_rotation_deg``, the force below ``max_force``
and the swing from growing.  Frequencies near a mode, its double or a sum of two modes are
skipped (:func:`resonances`).  A single steady harmonic cannot determine all six entries
(the body's angular velocity then stays in one plane: the moment of inertia about its normal
is seen only through the start-up transients), so a second run — complementary, or the same
again — is added when allowed; it may also use another cable geometry (``geometries``: the
lab's own, or :func:`geometry_variants`, the ceiling anchors moved), which changes the modes
and so the directions the rig moves in.  Pairs are ranked on short simulations and the best
few confirmed by full-length ones before one is chosen.  Objective: ``"baseline"`` (the least-improved entry as much
better than a baseline run as possible) or ``"relative"`` (the largest σ relative to the
entry: diagonals to themselves, products to the largest diagonal).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..estimation.prediction import PlanError, Prediction, combine
from ..estimation.propagation import Trajectory, predict_from_trajectory
from ..io.rig import Rig
from ..io.verdict import KEYS
from ..model.cables import CableModel
from ..model.dynamics import SimulationError
from ..model.equilibrium import equilibrium
from ..model.modes import natural_modes
from ..model.simulator import simulate
from .information import combined_std, tensor_covariance
from .run import SPIN_AXES, Body, Run, load_plan_input, make_body, recommended_band
from .screen import DesignScreen, linear_rig

# the public names, with those of planning_run that users import from here
__all__ = ["SPIN_AXES", "Body", "Candidate", "Plan", "PlanError", "PlanOptions", "Run", "amplitude_at_limits",
           "candidate_positions", "geometry_variants", "load_plan_input", "make_body", "plan_experiment", "resonances"]


@dataclass
class Candidate:
    """A screened run: the run, its (screen or simulated) prediction, the binding limit."""

    run: Run
    prediction: Prediction
    limit: str
    simulated: bool = False
    peak_rotation_deg: float | None = None
    min_tension_ratio: float | None = None
    band: tuple | None = None      # identification band to use (None: the identifier's automatic band)
    geometry: str | None = None    # None: the rig's own cables; else the other cable geometry's label
    body: "Body | None" = None     # the body on that geometry (None: the plan's)

    def to_dict(self) -> dict:
        geo = None
        if self.geometry is not None and self.body is not None:
            geo = {"label": self.geometry,
                   "cables": [{"name": c.name, "ceiling_anchor": [float(x) for x in c.ceiling_anchor],
                               "body_anchor": [float(x) for x in c.body_anchor], "length": float(c.length)}
                              for c in self.body.rig.cables]}
        return {"run": self.run.to_dict(), "cable_geometry": geo, "limit": self.limit, "simulated": self.simulated,
                "identification_band_hz": None if self.band is None else [float(x) for x in self.band],
                "peak_rotation_deg": self.peak_rotation_deg, "min_tension_ratio": self.min_tension_ratio,
                "prediction": self.prediction.to_dict()}


@dataclass
class Plan:
    """The recommended runs, their joint prediction, the baseline for comparison, the rig's
    modes and the limits used."""

    runs: list[Candidate]
    prediction: Prediction
    baseline: Candidate
    modes: list
    limits: dict
    notes: list[str] = field(default_factory=list)
    other_geometries: list = field(default_factory=list)   # per other cable geometry: its best second run
    rig_model: dict = field(default_factory=dict)   # "std", "baseline_std": (6,) kg·m², the rig model's bound

    def improvement(self) -> np.ndarray:
        """(6,) baseline σ / plan σ per entry (the rig model's bound where computed, else the
        gyro-only prediction's)."""
        if self.rig_model:
            return np.asarray(self.rig_model["baseline_std"] / self.rig_model["std"])
        return self.baseline.prediction.std / self.prediction.std

    def to_dict(self) -> dict:
        return {"modes": [m.to_dict() for m in self.modes],
                "runs": [c.to_dict() for c in self.runs],
                "prediction": self.prediction.to_dict(),
                "baseline": self.baseline.to_dict(),
                "improvement": {k: float(v) for k, v in zip(KEYS, self.improvement())},
                "rig_model": {k: {kk: float(v) for kk, v in zip(KEYS, a)} for k, a in self.rig_model.items()},
                "limits": dict(self.limits), "notes": list(self.notes),
                "other_geometries": [c.to_dict() for c in self.other_geometries]}


def candidate_positions(rig: Rig) -> list[np.ndarray]:
    """Mounting points: the corners of the box spanned by the body anchors and the rig's
    exciter position (body frame, m); a flat box (all anchors at one height, no exciter)
    keeps its two faces at the anchors' height and at the CG's."""
    pts = [*rig.body_anchors]
    if rig.exciter is not None:
        pts.append(rig.exciter.position)
    pts.append(rig.require_cg())
    pts = np.array(pts)
    lo, hi = pts.min(0), pts.max(0)
    return [np.array([x, y, z]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]


#: Times :func:`_fit_amplitude` rescales a run's force and simulates it again, at most.
AMPLITUDE_TRIES = 2


def _sim_check(body: Body, run: Run, limits: dict, settle: float, tracker_params,
               rot_f=None) -> tuple[Candidate, object]:
    """Simulate ``run`` without noise, measure its peak rotation, lowest tension ratio and
    whether the swing keeps growing (last third against the middle third), and predict.
    Returns (Candidate, SimResult)."""
    sim = simulate(body.experiment(run))
    rot = sim.states.rotation
    ang = np.linalg.norm((rot * rot[0].inv()).as_rotvec(), axis=1)
    peak = float(np.degrees(np.max(ang)))
    T = sim.states.tensions
    tmin = float(np.min(T / T[0][None, :]))
    n = len(ang)
    growing = bool(np.max(ang[2 * n // 3:]) > 1.15 * np.max(ang[n // 3: 2 * n // 3]))
    try:
        traj = Trajectory.from_simulation(sim)
    except PlanError:   # slack cables etc. leave too little to fit: scale down (see _fit_amplitude)
        cand = Candidate(run, None, "", True, peak, tmin)
        cand.growing = growing
        return cand, sim
    pred = predict_from_trajectory(traj, body.noise, settle, None, tracker_params)
    band = None
    if rot_f is not None:
        # the identifier's automatic band also takes in the weak difference tones of large
        # swings (f0 - f_mode), where the tracker's noise is large; a band around the exciter
        # and the rotational modes may do better: recommend it then
        rec = recommended_band(run.frequency, rot_f, traj.t[-1] - traj.t[0] - settle, float(body.rates["imu"]))
        pr = predict_from_trajectory(traj, body.noise, settle, rec, tracker_params)
        if pr.objective < 0.9 * pred.objective:
            pred, band = pr, rec
    cand = Candidate(run, pred, "", True, peak, tmin, band)
    cand.growing = growing
    return cand, sim


def _feasible(c: Candidate, limits: dict) -> bool:
    return (c.prediction is not None and c.peak_rotation_deg <= limits["max_rotation_deg"] * 1.001
            and c.min_tension_ratio >= limits["min_tension_ratio"] * 0.999 and not getattr(c, "growing", False)
            and c.run.amplitude <= limits["max_force_n"] * 1.001)


def _fit_amplitude(body: Body, run: Run, limits: dict, settle: float, tracker_params,
                   grow: bool = True, rot_f=None, say=None) -> Candidate | None:
    """Simulate ``run`` and bring its force amplitude to the limits: scale it linearly so
    that the simulated peak rotation and lowest tension (start-up transients and beats
    included) meet them with a 3 % margin, at most ``limits["max_force_n"]`` (up only if
    ``grow``), and simulate again (announced to ``say``, callable(str), when given), at most
    :data:`AMPLITUDE_TRIES` times.  None if the run still breaks a limit or its swing keeps
    growing (a parametric resonance)."""
    cand, _ = _sim_check(body, run, limits, settle, tracker_params, rot_f)
    for _ in range(AMPLITUDE_TRIES):
        if getattr(cand, "growing", False):
            return None
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
        cand, _ = _sim_check(body, run, limits, settle, tracker_params, rot_f)
        grow = False
    if not _feasible(cand, limits):
        return None
    use = {"rotation": cand.peak_rotation_deg / limits["max_rotation_deg"],
           "tension": (1 - cand.min_tension_ratio) / (1 - limits["min_tension_ratio"]),
           "force": run.amplitude / limits["max_force_n"]}
    cand.limit = max(use, key=use.get)   # the limit it comes closest to
    return cand


def amplitude_at_limits(body: Body, run: Run, max_rotation_deg: float = 3.0, min_tension_ratio: float = 0.2,
                        max_force: float = math.inf, settle: float = 5.0) -> Candidate | None:
    """``run`` (its frequency, exciter position and spin axis kept) at the largest force
    amplitude within the limits of :func:`plan_experiment` (same defaults): peak rotation ≤
    ``max_rotation_deg``, every cable ≥ ``min_tension_ratio`` × its static tension (start-up
    and beats included, 3 % margin), force ≤ ``max_force`` N; found by noise-free
    simulation as the planner does (:func:`_fit_amplitude`).  Returns the
    :class:`Candidate` (``.run.amplitude`` N, ``.peak_rotation_deg``,
    ``.min_tension_ratio``, ``.prediction``), or None if no amplitude keeps the run within
    the limits (its swing keeps growing).  Raises :class:`PlanError` for bad limits,
    :class:`~rig_identification.model.simulator.SimulationError`."""
    return _fit_amplitude(body, run, _limits(max_force, max_rotation_deg, min_tension_ratio), settle, None)


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
    candidates are simulated (``short`` s each).  settle: s the identifier leaves out at the
    start.  tracker_params: the tracker's, for the prediction (default its own).  geometries:
    other cable geometries the rig can take for the second run, [(label,
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
    tracker_params: dict | None = None
    geometries: tuple = ()


#: Frequencies screened per progress line of :func:`plan_experiment` (each line about 10 s on the thesis rig).
SCREEN_GROUP = 4


class _Search:
    """One plan's search (:func:`plan_experiment`): the limits, the reference σ the runs are
    ranked against, and the short and full-length simulations made so far (each run once)."""

    def __init__(self, body: Body, opts: PlanOptions, limits: dict, say, ref_screen: np.ndarray,
                 ref_sim: np.ndarray, rot_f: list[float]):
        self.body, self.opts, self.limits, self.say = body, opts, limits, say
        self.ref_screen, self.ref_sim = ref_screen, ref_sim
        self.short = min(opts.short, opts.duration)
        self.rot_fs: dict = {None: rot_f}   # per cable geometry: its rotational modes (Hz), for the band
        self.done: dict = {}
        self.full: dict = {}

    def worst(self, *cs: Candidate) -> float:
        """The worst entry's σ over the reference of ``cs`` done together."""
        return combine([c.prediction for c in cs]).worst(self.ref_sim)

    def search(self, b: Body, label: str | None, modes, scr: DesignScreen | None = None,
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
        rf = self.rot_fs.setdefault(label, _rotational(ms))
        scr = scr or DesignScreen(b, linear_rig(b), o.duration, o.settle, tracker_params=o.tracker_params)
        avoid = resonances(mf)
        freqs = [f for f in np.geomspace(o.frequencies[0], o.frequencies[1], 30)
                 if np.all(np.abs(f / avoid - 1) >= o.mode_margin)]
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
                screened += self._screen_frequency(scr, b, label, f, pts, rf)
        screened.sort(key=lambda c: c.prediction.worst(self.ref_screen))
        picks = _distinct(screened, o.refine)
        if partner is not None:   # a ranking only: the partner's prediction is simulated, the candidates' screened
            together = sorted(screened, key=lambda c: combine([partner.prediction, c.prediction]).worst(self.ref_sim))
            picks += [c for c in _distinct(together, o.refine) if all(not _same(c, o_) for o_ in picks)]
        singles = [x for x in (self.simulate_short(c, "a candidate run") for c in picks) if x is not None]
        return screened, singles

    def _screen_frequency(self, scr: DesignScreen, b: Body, label: str | None, f: float, pts: list[np.ndarray],
                          rf: list[float]) -> list[Candidate]:
        """The screened candidates at ``f`` Hz on the body ``b`` (cable geometry ``label``): every
        mounting point of ``pts`` (body m), spin axis and sense whose prediction is finite."""
        X = scr.responses(f)
        band = scr.band(f, rf)
        dens = scr.noise_density(band)
        out = []
        for p in pts:
            for ax in SPIN_AXES:
                for sense in (1, -1):
                    amp, lim, rot, tmin, pred = scr.candidate(X, p, SPIN_AXES[ax], self.limits, dens, band,
                                                              direction=sense)
                    if pred is None or not np.all(np.isfinite(pred.std)):
                        continue
                    out.append(Candidate(Run(float(f), float(amp), tuple(float(x) for x in p), ax, self.opts.duration,
                                             direction=sense), pred, lim, False, float(rot), float(tmin),
                                         geometry=label, body=b))
        return out

    def simulate_short(self, c: Candidate, what: str) -> Candidate | None:
        """``c`` simulated over ``short`` s, its amplitude brought to the limits, its prediction
        scaled to the full length; None if it breaks a limit."""
        key = _run_key(c)
        if key not in self.done:
            o = self.opts
            where = "" if c.geometry is None else f" ({c.geometry})"
            self.say(f"simulating {what}{where}: {c.run.frequency:.2f} Hz, {c.run.amplitude:.0f} N, spin axis "
                     f"{c.run.spin_axis}, at {np.round(c.run.position, 2).tolist()} m ({self.short:.0f} s) ...")
            cs = _fit_amplitude(c.body, replace(c.run, duration=self.short), self.limits, o.settle, o.tracker_params,
                                rot_f=self.rot_fs[c.geometry])
            if cs is not None:
                cs.prediction = cs.prediction.scaled((o.duration - o.settle) / cs.prediction.duration)
                cs.geometry, cs.body = c.geometry, c.body
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
                     f"{o.duration:.0f} s) ...")
            cf = _fit_amplitude(c.body, replace(c.run, duration=o.duration), self.limits, o.settle, o.tracker_params,
                                rot_f=self.rot_fs[c.geometry], say=self.say)
            if cf is not None:
                cf.geometry, cf.body = c.geometry, c.body
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


def _baseline(body: Body, baseline: Run, opts: PlanOptions, limits: dict, screen: DesignScreen, rot_f: list[float],
              say) -> tuple[Candidate, np.ndarray, np.ndarray]:
    """The baseline simulated in full and screened (each stage compares like with like):
    (its candidate, the reference σ of the screen's ranking, that of the simulations')."""
    say(f"simulating the baseline ({baseline.amplitude:.0f} N at {baseline.frequency:.2f} Hz, "
        f"{opts.duration:.0f} s) ...")
    base, _ = _sim_check(body, replace(baseline, duration=opts.duration), limits, opts.settle, opts.tracker_params)
    base.limit = "baseline"
    if base.prediction is None:
        raise PlanError(f"the baseline excitation ({baseline.amplitude:g} N at {baseline.frequency:g} Hz) slackens "
                        "cables so often that the identifier could not fit it; choose a gentler --baseline-force")
    bband = screen.band(baseline.frequency, rot_f)
    base_screen = screen.candidate(screen.responses(baseline.frequency), baseline.position, baseline.exciter_rpy,
                                   limits, screen.noise_density(bband), bband, baseline.amplitude)[4]
    if opts.objective == "baseline":
        return base, (base_screen.std if base_screen is not None else base.prediction.std), base.prediction.std
    return base, base.prediction.scale, base.prediction.scale


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
    for a, b in _best_pairs(screened, max(2, o.refine // 2), s.ref_screen):
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
    # the short runs' predictions, scaled to the full length, only rank the pairs (beats and
    # start-up weigh differently in 30 s): the best few that promise to beat the best run done
    # twice are simulated in full and compared in full
    repeat_short = s.worst(singles[0]) / math.sqrt(2)
    promising = [ab for ab in sorted(sims2, key=lambda ab: s.worst(*ab)) if s.worst(*ab) < repeat_short][:3]
    repeat = s.worst(first) / math.sqrt(2)
    best, best_val = None, repeat
    for a, b in promising:
        fa, fb = s.simulate_full(a, "a pair's first run"), s.simulate_full(b, "a pair's second run")
        if fa is not None and fb is not None and s.worst(fa, fb) < best_val:
            best, best_val = (fa, fb), s.worst(fa, fb)
        # a run simulated in full for a pair may itself be the better run to do twice than the
        # best screened single (with 20 s runs a pair's first run twice gave 0.306 of the
        # reference σ, the pair 0.388, the best single twice more)
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
        notes.append(f"no other run complements the best one better than itself: do it twice (every σ / √2; "
                     f"worst entry σ/reference {repeat:.3g} against {s.worst(first):.3g} for one run)")
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


def _rig_model_std(body: Body, base: Candidate, chosen: list[Candidate], say) -> dict:
    """The σ ``rig-identify inertia`` reaches: the rig model's bound, every sensor an output, of
    the chosen runs together and of the baseline (:mod:`~rig_identification.design.information`)."""
    bound: dict = {}
    for n, c in enumerate([base, *chosen]):
        key = _run_key(c)
        if key not in bound:
            what = "the baseline" if n == 0 else f"run {n}" if len(chosen) > 1 else "the run"
            say(f"the rig model's Cramér–Rao bound of {what} ({c.run.amplitude:.0f} N at {c.run.frequency:.2f} Hz: "
                "a simulation and a Jacobian) ...")
            bound[key] = tensor_covariance(simulate((c.body or body).experiment(c.run)), body.noise)
    return {"std": combined_std([bound[_run_key(c)] for c in chosen]),
            "baseline_std": combined_std([bound[_run_key(base)]])}


def plan_experiment(body: Body, baseline: Run, options: PlanOptions = PlanOptions(), progress=None) -> Plan:
    """Recommend one or two exciter runs (see module docstring).

    body: :class:`Body`.  baseline: the run to compare with (e.g. the thesis's 200 N at
    1.05 Hz at the rig's exciter).  options: :class:`PlanOptions` (limits, search, objective).
    progress: optional callable(str), called as each step starts: each group of
    :data:`SCREEN_GROUP` frequencies screened, each simulation, each run's Cramér–Rao bound.
    Raises :class:`PlanError`, :class:`~rig_identification.model.simulator.SimulationError`.
    """
    say = progress or (lambda s: None)
    limits = _checked_limits(options)
    rig = body.rig
    modes = natural_modes(rig, body.mass, rig.require_cg(), body.inertia, body.stiffness)
    rot_f = _rotational(modes)
    screen = DesignScreen(body, linear_rig(body), options.duration, options.settle,
                          tracker_params=options.tracker_params)
    base, ref_screen, ref_sim = _baseline(body, baseline, options, limits, screen, rot_f, say)
    s = _Search(body, options, limits, say, ref_screen, ref_sim, rot_f)
    screened, singles = s.search(body, None, modes, screen)
    if not screened:
        raise PlanError("no candidate run moves the body measurably")
    if not singles:
        raise PlanError("every screened candidate broke a limit in simulation (cable slack, rotation, growing "
                        "swing): lower --max-force or change the frequency range")
    singles.sort(key=s.worst)
    first = _first_run(s, singles)
    chosen, notes, others = [first], [], []
    if options.max_runs >= 2:
        chosen, notes, others = _second_run(s, first, singles, screened, modes)
    return Plan(chosen, combine([c.prediction for c in chosen]), base, modes, limits, notes, others,
                _rig_model_std(body, base, chosen, say))


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


def _rotational(modes) -> list[float]:
    """Frequencies (Hz) of the modes that are mostly rotation (> 30 % of their energy)."""
    return [m.frequency for m in modes if m.energy[3:].sum() > 0.3]


def _run_key(c: Candidate) -> tuple:
    """What makes a run distinct for the simulation caches: geometry, frequency, mounting
    point, spin axis and sense (the amplitude is fitted)."""
    return (c.geometry, c.run.frequency, c.run.position, c.run.spin_axis, c.run.direction)


def _best_pairs(cands: list[Candidate], n: int, ref: np.ndarray) -> list[tuple[Candidate, Candidate]]:
    """The ``n`` best distinct pairs of screened runs for a joint fit (information and noise
    of the two runs add; each with its own weights)."""
    B = np.array([np.einsum("a,aij->ij", c.prediction.weights, c.prediction.axis_bread) for c in cands])
    M = np.array([sum(np.einsum("a,b,abij->ij", c.prediction.weights, c.prediction.weights, m)
                      for m in c.prediction.axis_meats.values()) for c in cands])
    i, j = np.triu_indices(len(cands), 1)
    out = np.full(len(i), np.inf)
    for lo in range(0, len(i), 50000):
        sl = slice(lo, lo + 50000)
        Bs = B[i[sl]] + B[j[sl]]
        ok = np.linalg.cond(Bs) < 1e12
        Bi = np.zeros_like(Bs)
        Bi[ok] = np.linalg.inv(Bs[ok])
        var = np.einsum("pkl,plm,pkm->pk", Bi, M[i[sl]] + M[j[sl]], Bi)
        obj = np.max(np.sqrt(np.clip(var, 0, None)) / ref, axis=1)
        out[sl] = np.where(ok, obj, np.inf)
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
