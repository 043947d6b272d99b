"""Which causes explain the gap: a bounded search over sets of causes (``select_causes``).

Every candidate alone is cross-validated first (``selection.cross_validate_cause``; a cause with a
refinement, ``Cause.refined``, also refined); the best ``MAX_BRANCHES`` first steps that gain
``STEP_GAIN`` each start a path, the next one only while no path so far is settled: it fits the
noise (``noise.fits_noise``) with every channel within ``FIT_LIMIT`` (``settled``); when none gains,
or when the paths from those that gain end without fitting the noise, the best that gain at all
start one path together (``masked_path``). Along a path, while its model is not settled, each
forward step screens every remaining candidate by a short local fit next to the chosen causes
(``selection.screen_cause``), cross-validates the ``MAX_SCREENED`` best jointly with them, and those
with a refinement (the velocity scale per joint) refined too, by Gauss-Newton from their nominal
values; it adds the best one when it gains ``STEP_GAIN``, and, once the model fits the noise (a
channel beyond ``FIT_LIMIT`` left), only when that gain is also significant
(``selection.significant_gain``); an added cause with a refinement is then tried refined, kept when
that gains ``STEP_GAIN``; then each earlier cause is tried out (a backward step) and the one that
gains least is removed when it no longer gains ``STEP_GAIN`` over the others; when the model without
it fits better held out than with it, it is added back once from that model's fits (``readded``). A
path also stops when no step gains, at ``MAX_CAUSES`` causes, after ``MAX_PATH_STEPS`` accepted
steps or when the search has spent ``MAX_CROSS_VALIDATIONS``. The kept path is the one that fits the
noise with the lowest held-out error (else the lowest); its causes are selected when they remove
``EXPLAINED_GAIN`` of the nominal's excess over the noise floor. Every step of every path is
reported (``steps``). Rules and caps: ``docs/diagnosis.md``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np

from impactqp.sim.causes import Cause
from impactqp.sim.plant import PlantParameters
from impactqp.sim.process_pool import map_in_processes

from .fitting import FittedCauses, best_start, fit_report, trial_errors
from .intervals import gauss_newton_polish
from .noise import FIT_LIMIT, quadratic_mean
from .selection import (
    EXPLAINED_GAIN,
    SCREEN_GRID_STRIDE,
    STEP_GAIN,
    CandidateTask,
    ModelTask,
    ScreenTask,
    cross_validate_cause,
    cross_validate_model,
    fold_of,
    gain_over_floor,
    relative_gain,
    screen_cause,
    significant_gain,
)
from .start_spread import start_spread
from .trials import ReplaySetting, replay_all

log = logging.getLogger(__name__)

MAX_CAUSES = 3
MAX_BRANCHES = 3  # paths, one per first step among the best three that gain
MAX_SCREENED = 3  # candidates cross-validated per forward step, the best of the screen
MAX_PATH_STEPS = 6  # additions, refinements and removals per path
MAX_CROSS_VALIDATIONS = 48  # per search, every candidate of the first step included


@dataclass
class Branch:
    """One path of the search: the chosen causes fitted jointly on all trials (``model``) and
    without each fold (``folds``), the steps taken and the held-out normalised residuals and
    errors (26) per trial of the last one (of the nominal replay before any step)."""

    model: FittedCauses
    folds: list[FittedCauses]
    steps: list[dict]
    heldout: np.ndarray
    heldout_jump: np.ndarray
    visited: set = field(default_factory=set)  # the sets of cause names reached (no cycles)

    @property
    def error(self) -> float:
        return quadratic_mean(self.heldout)

    def names(self) -> frozenset:
        return frozenset(c.name for c in self.model.causes)


@dataclass
class Selection:
    """The result of the search (``select_causes``)."""

    candidates: list[dict]  # the first step: every candidate alone
    steps: list[dict]  # every step of every path tried, the kept path first
    model: FittedCauses  # the selected causes, refitted jointly on all trials
    best: FittedCauses  # the kept path's causes, else the best first-step candidate alone
    heldout_errors: np.ndarray  # normalised residual per trial, of ``model`` if it has causes, else of ``best``
    heldout_jump_errors: np.ndarray  # error (26) per trial, likewise
    gain_over_floor: float  # of the held-out errors above, against the nominal's


@dataclass
class Search:
    """What every step of the search shares: the candidates, the data and the budget left."""

    causes: list[Cause]
    nominal: PlantParameters
    setting: ReplaySetting
    trials: list
    jobs: int
    budget: int = MAX_CROSS_VALIDATIONS

    def run(self, function, tasks: list, what: str, labels: list[str]) -> list:
        """``function`` over ``tasks`` (each cross-validation spends the budget, a screen does
        not), each result logged as it comes: ``diagnose: WHAT k/n LABEL``, a note (INFO) for a
        cross-validated model set, a debug line for a screen."""
        screen = function is screen_cause
        self.budget -= 0 if screen else len(tasks)

        def done(k: int, total: int) -> None:
            log.log(logging.DEBUG if screen else logging.INFO, "diagnose: %s %d/%d %s", what, k, total, labels[k - 1])

        return map_in_processes(function, tasks, self.jobs, done)

    def settled(self, branch: Branch) -> tuple[Branch, bool, bool]:
        """``branch`` with its model polished (``intervals.gauss_newton_polish``: the fit of a
        step stops after a few evaluations), whether that model fits the noise and whether it
        is settled (``settled``)."""
        if not branch.model.causes:
            return branch, False, False
        model = gauss_newton_polish(branch.model, self.nominal, self.setting, self.trials)[0]
        plant = model.plant(self.nominal)
        spreads = start_spread(self.setting, plant, self.trials, self.jobs)
        report = fit_report(replay_all(self.setting, plant, self.trials), self.trials, spreads)
        return replace(branch, model=model), report["fits_noise"], settled(report)


def settled(report: dict) -> bool:
    """Whether a fit (``fitting.fit_report``) leaves nothing for a further cause: it fits the noise
    and its worst channel, one joint's part of a block, is within ``FIT_LIMIT`` too (a block's
    limit): one channel beyond it may hide a second cause of that joint behind the blocks' means
    (joint 6's velocity scale behind joint damping: ``docs/diagnosis.md``)."""
    return bool(report["fits_noise"] and report["worst_channel"]["value"] <= FIT_LIMIT)


def model_label(model: FittedCauses) -> str:
    """The causes of ``model`` joined by '+' (a model set in the progress notes)."""
    return "+".join(c.name for c in model.causes) or "nominal"


def search_step(action: str, cause: str, heldout_error: float, gain: float, accepted: bool, path: int) -> dict:
    """One entry of ``steps``: which path, what was tried (add, refine, remove) with which cause,
    the held-out error after it, the gain (of the cause over the model without it) and whether
    the path took it; ``selected`` is set once the kept path is known. Logged (DEBUG)."""
    log.debug("diagnose: path %d %s %s: held-out residual %.4f, gain %.1f %%, %s", path + 1, action, cause,
              heldout_error, 100 * gain, "taken" if accepted else "not taken")
    return {"path": path, "action": action, "cause": cause, "heldout_error": float(heldout_error),
            "gain": float(gain), "accepted": bool(accepted), "selected": False}


def first_added(branch: Branch, cause: Cause, result: dict, step: dict) -> Branch:
    """The nominal ``branch`` after its first step: ``cause`` alone, cross-validated (``result``)."""
    folds = [FittedCauses((cause,), (u,)) for u in result["u_folds"]]
    model = FittedCauses((cause,), (result["u"],))
    heldout, heldout_jump = result["heldout"], result["heldout_jump"]
    return Branch(model, folds, branch.steps + [step], heldout, heldout_jump, {frozenset([cause.name])})


def last_first(model: FittedCauses) -> FittedCauses:
    """``model`` with its first cause (a candidate fitted first) moved to the end: the causes in
    the order chosen (they touch distinct plant keys: the same plant)."""
    return FittedCauses(model.causes[1:] + model.causes[:1], model.u[1:] + model.u[:1])


def forward(search: Search, branch: Branch, path: int, past_noise: bool) -> Branch | None:
    """One forward step: screen, cross-validate the best ``MAX_SCREENED`` jointly with the chosen
    causes and those with a refinement refined too (``refined_tasks``), add the best when it gains
    ``STEP_GAIN`` and, ``past_noise`` (the model fits the noise already), when its gain is
    significant too (None otherwise, the rejected step recorded on ``branch``)."""
    pool = [c for c in search.causes if c.name not in branch.names()
            and branch.names() | {c.name} not in branch.visited]
    if not pool or search.budget <= 0:
        return None
    trials = tuple(search.trials)
    features = replay_all(search.setting, branch.model.plant(search.nominal), search.trials)
    current = quadratic_mean(trial_errors(features, search.trials))
    screens = [ScreenTask(c, branch.model, search.nominal, search.setting, trials) for c in pool]
    screened = search.run(screen_cause, screens, f"path {path + 1} screen",
                          [f"{c.name} next to {model_label(branch.model)}" for c in pool])
    order = [int(i) for i in np.argsort([e for e, _ in screened], kind="stable")
             if screened[i][0] <= (1 - STEP_GAIN / 2) * current][: min(MAX_SCREENED, search.budget)]
    tasks = [ModelTask(screened[i][1], tuple(branch.folds), search.nominal, search.setting, trials, pool[i])
             for i in order]
    tasks += refined_tasks(search, branch, [pool[i] for i in order])[: max(search.budget - len(tasks), 0)]
    if not tasks:
        return None
    results = search.run(cross_validate_model, tasks, f"path {path + 1} model",
                         [model_label(t.model) for t in tasks])
    errors = [quadratic_mean(r["heldout"]) for r in results]
    best = int(np.argmin(errors))
    gain = relative_gain(errors[best], branch.error)
    taken = gain >= STEP_GAIN and (not past_noise or significant_gain(branch.heldout, results[best]["heldout"]))
    step = search_step("add", tasks[best].model.causes[0].name, errors[best], gain, taken, path)
    if not taken:
        branch.steps.append(step)
        return None
    result = results[best]
    result = {**result, "model": last_first(result["model"]), "folds": [last_first(f) for f in result["folds"]]}
    return as_branch(branch, result, step)


def refined_tasks(search: Search, branch: Branch, pool: list[Cause]) -> list[ModelTask]:
    """The cross-validation of every screened candidate of ``pool`` that has a refinement
    (``Cause.refined``), refined, next to the chosen causes: started from its nominal values on
    top of their fit, every fit a Gauss-Newton polish (``ModelTask.newton``). The global scale
    cannot fit one joint's fault, and a short local fit does not move seven scales at once:
    one joint's scale next to joint damping gained 14 % held out as a global scale, while the
    seven scales reach the noise (``docs/diagnosis.md``)."""
    tasks = []
    for cause in pool:
        finer = cause.refined()
        if finer is not None:
            start = FittedCauses((finer,) + branch.model.causes, (finer.to_u(finer.nominal_theta(search.nominal)),)
                                 + branch.model.u)
            tasks.append(ModelTask(start, tuple(branch.folds), search.nominal, search.setting, tuple(search.trials),
                                   finer, newton=True))
    return tasks


def as_branch(branch: Branch, result: dict, step: dict) -> Branch:
    """``branch`` moved to the model of a cross-validated ``result`` (``cross_validate_model``)."""
    model = result["model"]
    visited = branch.visited | {frozenset(c.name for c in model.causes)}
    heldout, heldout_jump = result["heldout"], result["heldout_jump"]
    return Branch(model, list(result["folds"]), branch.steps + [step], heldout, heldout_jump, visited)


def refined(model: FittedCauses, finer: Cause) -> FittedCauses:
    """``model`` with its last cause replaced by ``finer``, started from the last cause's fit."""
    cause, u = model.causes[-1], model.u[-1]
    start = finer.to_u(finer.theta_of(cause.overrides(cause.to_theta(u))))
    return FittedCauses(model.causes[:-1] + (finer,), model.u[:-1] + (start,))


def refine(search: Search, branch: Branch, path: int) -> Branch:
    """The last added cause replaced by its refinement (``Cause.refined``), started from its
    fitted value, when that gains ``STEP_GAIN`` held out; else ``branch`` with the try recorded."""
    finer = branch.model.causes[-1].refined()
    if finer is None or search.budget <= 0:
        return branch
    task = ModelTask(refined(branch.model, finer), tuple(refined(f, finer) for f in branch.folds), search.nominal,
                     search.setting, tuple(search.trials), newton=True)
    [result] = search.run(cross_validate_model, [task], f"path {path + 1} refined model", [model_label(task.model)])
    cause = branch.model.causes[-1]
    error = quadratic_mean(result["heldout"])
    gain = relative_gain(error, branch.error)
    step = search_step("refine", cause.name, error, gain, gain >= STEP_GAIN, path)
    if gain < STEP_GAIN:
        branch.steps.append(step)
        return branch
    return as_branch(branch, result, step)


def without(model: FittedCauses, k: int) -> FittedCauses:
    """``model`` without its cause ``k``."""
    keep = [j for j in range(len(model.causes)) if j != k]
    return FittedCauses(tuple(model.causes[j] for j in keep), tuple(model.u[j] for j in keep))


def backward(search: Search, branch: Branch, path: int) -> Branch:
    """Each cause chosen before the last one tried out (the others refitted jointly and
    cross-validated); the one whose removal leaves the lowest held-out error is removed when it
    gains less than ``STEP_GAIN`` over the others (1 - error with it / error without it)."""
    earlier = [k for k, c in enumerate(branch.model.causes[:-1]) if branch.names() - {c.name} not in branch.visited]
    if len(branch.model.causes) < 2 or not earlier or search.budget < len(earlier):
        return branch
    tasks = [ModelTask(without(branch.model, k), tuple(without(f, k) for f in branch.folds), search.nominal,
                       search.setting, tuple(search.trials)) for k in earlier]
    results = search.run(cross_validate_model, tasks, f"path {path + 1} model without a cause",
                         [model_label(t.model) for t in tasks])
    errors = [quadratic_mean(r["heldout"]) for r in results]
    best = int(np.argmin(errors))
    steps = []
    for i, k in enumerate(earlier):
        gain = relative_gain(branch.error, errors[i])
        taken = i == best and gain < STEP_GAIN
        steps.append(search_step("remove", branch.model.causes[k].name, errors[i], gain, taken, path))
    if not steps[best]["accepted"]:
        branch.steps.extend(steps)
        return branch
    branch.steps.extend(s for i, s in enumerate(steps) if i != best)
    reduced = as_branch(branch, results[best], steps[best])
    if errors[best] < branch.error:  # fewer causes fit better held out: the larger set's fit was stuck
        return readded(search, reduced, branch.model.causes[earlier[best]], path)
    return reduced


def readded(search: Search, branch: Branch, cause: Cause, path: int) -> Branch:
    """``cause``, just removed because the model without it fits better held out (a set can fit no
    worse than its subset: its fit had stopped far from its best), added back once from
    ``branch``'s fits (from its best grid point, ``ModelTask.added``), cross-validated jointly;
    taken when it gains ``STEP_GAIN`` over ``branch``, else ``branch`` with the try recorded."""
    if search.budget <= 0:
        return branch
    base = branch.model.plant(search.nominal)
    index, points, _ = best_start(cause, base, search.setting, search.trials, stride=SCREEN_GRID_STRIDE)
    start = FittedCauses((cause,) + branch.model.causes, (points[index],) + branch.model.u)
    task = ModelTask(start, tuple(branch.folds), search.nominal, search.setting, tuple(search.trials), cause)
    [result] = search.run(cross_validate_model, [task], f"path {path + 1} model again", [model_label(start)])
    gain = relative_gain(quadratic_mean(result["heldout"]), branch.error)
    step = search_step("add", cause.name, quadratic_mean(result["heldout"]), gain, gain >= STEP_GAIN, path)
    if gain < STEP_GAIN:
        branch.steps.append(step)
        return branch
    result = {**result, "model": last_first(result["model"]), "folds": [last_first(f) for f in result["folds"]]}
    return as_branch(branch, result, step)


def follow(search: Search, branch: Branch, path: int) -> tuple[Branch, bool, bool]:
    """Forward steps, each followed by a refinement try and a backward step, while the model
    is not settled (``settled``), until no step gains, ``MAX_CAUSES`` causes are chosen,
    ``MAX_PATH_STEPS`` steps are taken or the budget is spent. Returns the path's end, whether
    its (polished) model fits the noise and whether it is settled."""
    branch, fits, done = search.settled(refine(search, branch, path))
    while len(branch.model.causes) < MAX_CAUSES and sum(s["accepted"] for s in branch.steps) < MAX_PATH_STEPS:
        if done:
            break
        step = forward(search, branch, path, fits)
        if step is None:
            break
        branch, fits, done = search.settled(backward(search, refine(search, step, path), path))
    return branch, fits, done


def marked(steps: list[dict], causes: list[str]) -> list[dict]:
    """The steps with ``selected`` set on the last accepted addition of each of ``causes``."""
    last = {s["cause"]: i for i, s in enumerate(steps) if s["action"] == "add" and s["accepted"]}
    chosen = {last[c] for c in causes}
    return [{**s, "selected": i in chosen} for i, s in enumerate(steps)]


def first_steps(search: Search, start: Branch) -> tuple[list[Cause], list[dict], list[dict]]:
    """Every candidate alone, cross-validated: the candidates (a cause replaced by its
    refinement when that gains, ``refined_first``), their results and the ``candidates``
    entries."""
    trials = tuple(search.trials)
    tasks = [CandidateTask(c, search.nominal, search.setting, trials) for c in search.causes]
    results = search.run(cross_validate_cause, tasks, "candidate model", [c.name for c in search.causes])
    causes = list(search.causes)
    for k, (cause, result) in enumerate(zip(search.causes, results)):
        causes[k], results[k] = refined_first(search, start, cause, result)
    candidates = []
    for c, r in zip(causes, results):
        e = quadratic_mean(r["heldout"])
        candidates.append({"cause": c.name, "parameters": c.overrides(c.to_theta(r["u"])), "heldout_error": e,
                           "gain": relative_gain(e, start.error), "gain_over_floor": gain_over_floor(e, start.error)})
    return causes, results, candidates


def refined_first(search: Search, start: Branch, cause: Cause, result: dict) -> tuple[Cause, dict]:
    """A first-step candidate with a refinement (``Cause.refined``), global first: its
    refinement, started from the global fit and cross-validated, takes its place if it gains
    ``STEP_GAIN`` over it (one joint's velocity scale: the global one alone gains nothing)."""
    finer = cause.refined()
    error = quadratic_mean(result["heldout"])
    if finer is None or search.budget <= 0:
        return cause, result
    folds = tuple(refined(FittedCauses((cause,), (u,)), finer) for u in result["u_folds"])
    task = ModelTask(refined(FittedCauses((cause,), (result["u"],)), finer), folds, search.nominal, search.setting,
                     tuple(search.trials), newton=True)
    [model] = search.run(cross_validate_model, [task], "candidate refined", [model_label(task.model)])
    if relative_gain(quadratic_mean(model["heldout"]), error) < STEP_GAIN:
        return cause, result
    return finer, {"cause": cause.name, "u": model["model"].u[0], "u_folds": [f.u[0] for f in model["folds"]],
                   "heldout": model["heldout"], "heldout_jump": model["heldout_jump"]}


def masked_path(search: Search, start: Branch, causes: list[Cause], results: list[dict],
                steps: list[dict], path: int) -> tuple[bool, Branch] | None:
    """Path number ``path`` when no candidate alone gains ``STEP_GAIN``, or when the paths from
    those that gain end without fitting the noise (``causes``, their first-step cross-validations
    ``results``, best first; ``steps``: the path's record before it): large hidden causes mask one
    another, so each alone fits little (docs/diagnosis.md, "Causes that mask each other"). The
    ``MAX_CAUSES`` best that gain at all start one path together, each from its fit alone (on all
    trials and in each fold), cross-validated jointly, then a backward step and ``follow``. The
    path (its ``fits_noise`` and end) is kept when its k causes gain at least ``STEP_GAIN`` each on
    average over the nominal, 1 - E / E_0 >= 1 - (1 - STEP_GAIN)^k; None otherwise, and with fewer
    than two that gain."""
    chosen = [(c, r) for c, r in zip(causes, results)
              if relative_gain(quadratic_mean(r["heldout"]), start.error) > 0.0][:MAX_CAUSES]
    if len(chosen) < 2 or search.budget <= 0:
        return None
    together = FittedCauses(tuple(c for c, _ in chosen), tuple(r["u"] for _, r in chosen))
    folds = tuple(FittedCauses(together.causes, tuple(r["u_folds"][k] for _, r in chosen))
                  for k in range(len(start.folds)))
    task = ModelTask(together, folds, search.nominal, search.setting, tuple(search.trials))
    [result] = search.run(cross_validate_model, [task], f"path {path + 1} model", [model_label(together)])
    error = quadratic_mean(result["heldout"])
    gain = relative_gain(error, start.error)
    added = [search_step("add", c.name, error, gain, True, path) for c in together.causes]
    branch = as_branch(replace(start, steps=steps + added[:-1]), result, added[-1])
    branch, fits, _ = follow(search, backward(search, branch, path), path)
    if relative_gain(branch.error, start.error) < 1.0 - (1.0 - STEP_GAIN) ** len(branch.model.causes):
        return None
    return fits, branch


def select_causes(
    causes: list[Cause], nominal: PlantParameters, setting: ReplaySetting, trials, baseline: tuple, jobs: int
) -> Selection:
    """The search of the module docstring. ``baseline``: the nominal replays' normalised
    residual and error (26) per trial."""
    search = Search(causes, nominal, setting, trials, jobs)
    folds = len(np.unique(fold_of(trials)))
    start = Branch(FittedCauses(), [FittedCauses()] * folds, [], *(np.asarray(b, float) for b in baseline))
    causes, results, candidates = first_steps(search, start)
    errors = [c["heldout_error"] for c in candidates]
    order = [int(i) for i in np.argsort(errors, kind="stable")]
    ranked, ranked_results = [causes[k] for k in order], [results[k] for k in order]
    paths: list[tuple[bool, Branch]] = []
    done = False  # a path so far is settled
    masked_tried = False
    for i in order[:MAX_BRANCHES]:
        gain = relative_gain(errors[i], start.error)
        step = search_step("add", causes[i].name, errors[i], gain, gain >= STEP_GAIN, len(paths))
        if gain < STEP_GAIN or done:
            if not paths:  # nothing gains alone: causes that mask each other, else the nominal path
                paths.append(masked_path(search, start, ranked, ranked_results, [step], 0)
                             or (False, replace(start, steps=[step])))
                masked_tried = True
            break
        branch, fits, done = follow(search, first_added(start, causes[i], results[i], step), len(paths))
        paths.append((fits, branch))
    if not masked_tried and not any(fits for fits, _ in paths):  # one just gained alone, the others masked
        masked = masked_path(search, start, ranked, ranked_results, [], len(paths))
        if masked is not None:
            paths.append(masked)
    kept = min(range(len(paths)), key=lambda p: (not paths[p][0], paths[p][1].error))
    chosen = paths[kept][1]
    floor_gain = gain_over_floor(chosen.error, start.error)
    selected = bool(chosen.model.causes) and floor_gain >= EXPLAINED_GAIN
    names = [c.name for c in chosen.model.causes] if selected else []
    steps = marked(chosen.steps, names) + [s for p, (_, b) in enumerate(paths) if p != kept for s in b.steps]
    if chosen.model.causes:
        model = chosen.model if selected else FittedCauses()
        return Selection(candidates, steps, model, chosen.model, chosen.heldout, chosen.heldout_jump, floor_gain)
    best = order[0]
    heldout = results[best]["heldout"]
    return Selection(
        candidates, steps, FittedCauses(), FittedCauses((causes[best],), (results[best]["u"],)), heldout,
        results[best]["heldout_jump"], gain_over_floor(quadratic_mean(heldout), start.error),
    )
