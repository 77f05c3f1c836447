"""The ``controllers`` study: stride-to-stride controllers on one gait, and their basins.

The gait is the problem's fixed point, under its hip law. For each box size b of
``boxes``, apex states are drawn uniformly from the box X* +- b * ``perturbation`` (four
dimensions, seeded, one draw per box shared by the controllers); from each, a controller
runs for at most ``strides`` strides (:mod:`baslip.analysis.feedback`):

* ``constant``: the constant hip law, u = u*;
* ``feedback``: u = u* + K (X - X*), saturated at the controls' bounds. K is deadbeat where
  dr/du has rank 4 and its controls stay within their bounds over the smallest box;
  otherwise discrete LQR, with the weights ``lqr_scale`` if given, else chosen by the tool
  (:mod:`baslip.analysis.tuning`) for the largest converged share of a pilot sample;
* ``pivot`` (VPP law): the same, adapting the pivot r_vpp alone at every apex, the touchdown
  angle held at the gait's (Sharbafi et al. 2013 adapt the pivot by discrete LQR);
* ``horizon``: the next ``horizon`` strides' controls re-solved at every apex so that the
  apex after them is X* (:mod:`baslip.analysis.horizon`);
* ``resolve``: u re-solved at every apex for the next stride alone (``criterion``: thesis
  or tracking).

``constant``, ``feedback`` and ``pivot`` run ``samples`` starts a box, in lockstep through the batched
engine; the two re-solving controllers run their ``solve_samples`` (the first of the same draws).
A run has *converged* once an apex is within ``tolerance`` (eq. 4.1) of X*. At a gait with
a structural multiplier 1 (the symmetry of a VPP gait, energy without torque), whose
direction no control reaches at first order, a run whose apex repeats to ``tolerance``
elsewhere has *settled* on a neighbouring gait of the family. A run is *bounded* if it did
neither and did not fall. A basin is the share of a box that converged, or settled, with
its Wilson 95 % interval; the largest box where that share is at least 90 % is reported.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from baslip.analysis.feedback import (
    ConstantControl,
    LinearFeedback,
    ResolvedControl,
    closed_loop_multipliers,
    control_rank,
    control_scale,
    lqr_gain_for_gait,
    run_closed_loop,
    run_closed_loop_many,
)
from baslip.analysis.horizon import RecedingHorizon
from baslip.analysis.tuning import FeedbackChoice, choose_feedback, transverse_radius
from baslip.diagnostics import logger
from baslip.engine.returnmap import ReturnMap, Tolerances
from baslip.files.rows import read_points
from baslip.gait.polish import eps
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import HipLaw
from baslip.model.quantities import NOMINAL
from baslip.numerics.intervals import wilson_interval
from baslip.problem.reader import Problem
from baslip.problem.study import ADAPTED_CONTROLS, RESOLVING, Controllers
from baslip.studies.common import StudyFailed, run_info, study_table
from baslip.studies.runner import Workers, run_tasks
from baslip.viz.labels import problem_title

_log = logger(__name__)

#: Controllers whose control depends on the apex alone: their runs go in lockstep batches.
BATCHED = ("constant", "feedback", "pivot")
#: The linear feedbacks, each the gain of its own LQR (or deadbeat) choice.
LINEAR = ("feedback", "pivot")
CONTROLLER_COLUMNS = [
    "controller", "box", "sample", *(f"d_{n}" for n in APEX.names), "outcome", "strides_run", "strides_to_converge",
    "final_eps", "max_residual", "ms_per_stride",
]
#: Significant digits of a row's measured cost a stride: run to run it moves by up to
#: 25 %, so further digits are noise (at full precision they were 13 % of a
#: controllers.csv of 80,500 rows).
COST_DIGITS = 3
#: The share of a box that must return (converge or settle) for it to count as inside the basin.
BASIN_SHARE = 0.9
#: The outcomes that count as a return to the gait (or, where it has one, to its family).
RETURNED = ("converged", "settled")
#: Starts and strides of the pilot sample that tunes the LQR weights, and its seed offset.
PILOT_STARTS, PILOT_STRIDES, PILOT_SEED = 100, 60, 1_000_003


def box_deltas(study: Controllers) -> dict[float, np.ndarray]:
    """The perturbations of each box (samples x 4, SI units and rad), drawn once, in order."""
    rng = np.random.default_rng(study.seed)
    widths = np.array([dict(study.perturbation).get(n, 0.0) for n in APEX.names])
    return {box: rng.uniform(-1, 1, size=(study.samples, APEX.size)) * widths * box for box in study.boxes}


def controller_tasks(study: Controllers) -> list[dict]:
    """Every (controller, box, sample) with its perturbation."""
    tasks = []
    for box, deltas in box_deltas(study).items():
        for name in study.controllers:
            tasks += [{"controller": name, "box": box, "sample": k,
                       **{f"d_{n}": round(float(v), 15) for n, v in zip(APEX.names, delta)}}
                      for k, delta in enumerate(deltas[: study.starts(name)])]
    return tasks


def adds_starts(old: dict, new: dict) -> bool:
    """Whether the resolved study section ``new`` only adds starts to ``old``'s.

    True when the two differ in ``solve_samples`` alone and no re-solving controller gets
    fewer starts. Its starts are the first of the same draws (which ``samples`` and
    ``seed`` fix), and each row depends on its own start alone, so the rows of ``old``
    stay valid: a run of ``new`` in ``old``'s folder computes only the added starts.

    Parameters
    ----------
    old, new : dict
        The ``study`` entries of two resolved problems' provenance records.
    """
    def others(study: dict) -> dict:
        return {key: value for key, value in study.items() if key != "solve_samples"}

    def starts(study: dict, name: str) -> int:
        return min(dict(study.get("solve_samples") or ()).get(name, study["samples"]), study["samples"])

    if old.get("kind") != "controllers" or others(old) != others(new):
        return False
    return all(starts(new, name) >= starts(old, name) for name in RESOLVING)


def lqr_weights(study: Controllers) -> np.ndarray:
    """Q of an LQR with given weights: an apex deviation of lqr_scale (default: the nominal
    size) costs as much as a nominal change of a control."""
    scale = dict(study.lqr_scale)
    return np.diag([1 / scale.get(n, NOMINAL[n]) ** 2 for n in APEX.names])


def make_controller(name: str, context: dict, rmap: ReturnMap):
    """A fresh controller of kind ``name`` for the gait in ``context``."""
    X, u, params = context["X"], context["u"], context["params"]
    bounds = {"lower": context["lower"], "upper": context["upper"]}
    if name == "constant":
        return ConstantControl(u)
    if name in LINEAR:
        return LinearFeedback(X, u, context["gains"][name], context["lower"], context["upper"])
    if name == "horizon":  # the tuned feedback's plan is its search's second start
        return RecedingHorizon(rmap, params, X, u, context["horizon"], fixed=context["held"], family=context["settle"],
                               K=context["gains"]["feedback"], **bounds)
    return ResolvedControl(rmap, params, X, u, context["criterion"], fixed=context["held"], **bounds)


def controllers_worker(chunk: list[dict], context: dict, queue) -> None:
    """Worker process: the batched controllers' tasks in lockstep, then the others one by one."""
    rmap = ReturnMap(Tolerances(1e-12, 1e-12), law=context["law"])
    pending = [task for task in chunk if not task.get("done")]
    for name in BATCHED:
        mine = [task for task in pending if task["controller"] == name]
        if mine:
            # news for the parent's progress line while the batch runs
            _log.info(f"controller {name}: {len(mine)} run{'s' * (len(mine) > 1)} in lockstep")
            for row in _batched_rows(mine, context, rmap):
                queue.put(row)
    for task in pending:
        if task["controller"] not in BATCHED:
            _log.info(f"controller {task['controller']}: a run with its re-solves")
            queue.put(_solved_row(task, context, rmap))


def ms_per_stride(seconds: float, strides: int) -> float:
    """A run's or a batch's cost [ms] a stride, to :data:`COST_DIGITS` significant digits."""
    return float(f"{1e3 * seconds / max(strides, 1):.{COST_DIGITS}g}")


def _start(task: dict, context: dict) -> np.ndarray:
    return context["X"] + np.array([task[f"d_{n}"] for n in APEX.names])


def _batched_rows(tasks: list[dict], context: dict, rmap: ReturnMap) -> list[dict]:
    """Rows of a batched controller's tasks; ms_per_stride is the batch's time per stride."""
    controller = make_controller(tasks[0]["controller"], context, rmap)
    started = time.perf_counter()
    outcomes = run_closed_loop_many(rmap, context["params"], controller, np.array([_start(t, context) for t in tasks]),
                                    context["X"], context["strides"], context["tolerance"], context["settle"])
    per_stride = ms_per_stride(time.perf_counter() - started, sum(o.strides_run for o in outcomes))
    return [{**task, "outcome": o.outcome, "strides_run": o.strides_run, "strides_to_converge": o.strides_to_converge,
             "final_eps": o.final_eps, "max_residual": 0.0, "ms_per_stride": per_stride}
            for task, o in zip(tasks, outcomes)]


def _solved_row(task: dict, context: dict, rmap: ReturnMap) -> dict:
    controller = make_controller(task["controller"], context, rmap)
    started = time.perf_counter()
    run = run_closed_loop(rmap, context["params"], controller, _start(task, context), context["X"], context["strides"],
                          context["tolerance"], context["settle"])
    elapsed = time.perf_counter() - started
    return {**task, "outcome": run.outcome, "strides_run": len(run.controls), "strides_to_converge": run.strides_to_converge,
            "final_eps": eps(run.apexes[-1], context["X"]),
            "max_residual": float(np.max(run.residuals)) if len(run.residuals) else 0.0,
            "ms_per_stride": ms_per_stride(elapsed, len(run.controls))}


def feedback_for(study: Controllers, context: dict, A, B, scale, rmap: ReturnMap,
                 adapted: np.ndarray | None = None) -> FeedbackChoice:
    """The feedback for the gait: LQR with the study's ``lqr_scale`` weights if given, else
    the tool's choice (:func:`baslip.analysis.tuning.choose_feedback`, with a pilot sample
    in the box nearest 4x), moving the ``adapted`` controls only.

    Parameters
    ----------
    study : Controllers
        The study (its perturbation, boxes, seed, strides and weights).
    context : dict
        The gait: ``X``, ``u``, ``params``, ``lower``, ``upper``, ``tolerance``, ``settle``
        and ``neutral`` (as :func:`run_controllers` builds it).
    A, B : numpy.ndarray
        dr/dX and dr/du at the gait.
    scale : numpy.ndarray
        The controls' nominal sizes.
    rmap : ReturnMap
        The map the pilot runs on.
    adapted : numpy.ndarray, optional
        Indices of the controls the feedback moves (default: all); the gain's other rows
        are zero, so those controls keep the gait's values.
    """
    adapted = np.arange(B.shape[1]) if adapted is None else np.asarray(adapted)

    def full(K_adapted: np.ndarray) -> np.ndarray:
        K = np.zeros((B.shape[1], APEX.size))
        K[adapted] = K_adapted
        return K

    widths = np.array([dict(study.perturbation).get(n, 0.0) for n in APEX.names])
    B_adapted, scale_adapted = B[:, adapted], scale[adapted]
    if study.lqr_scale:
        K = full(lqr_gain_for_gait(A, B_adapted, lqr_weights(study), np.diag(1 / scale_adapted**2),
                                     context["neutral"]))
        radius = transverse_radius(A, B, K, context["neutral"])
        return FeedbackChoice("lqr", K, (), radius, None, 1, "LQR weights given by the problem (lqr_scale)")
    pilot_box = min(study.boxes, key=lambda b: abs(math.log(b / 4.0)))  # the box nearest 4x
    starts = context["X"] + np.random.default_rng(study.seed + PILOT_SEED).uniform(
        -1, 1, size=(PILOT_STARTS, APEX.size)) * widths * pilot_box

    def pilot(K_adapted: np.ndarray) -> float:
        controller = LinearFeedback(context["X"], context["u"], full(K_adapted), context["lower"], context["upper"])
        runs = run_closed_loop_many(rmap, context["params"], controller, starts, context["X"],
                                    min(study.strides, PILOT_STRIDES), context["tolerance"], context["settle"])
        return sum(r.outcome in RETURNED for r in runs) / len(runs)

    choice = choose_feedback(A, B_adapted, context["u"][adapted], context["lower"][adapted], context["upper"][adapted],
                             widths * min(study.boxes), scale_adapted, pilot, context["neutral"])
    return replace(choice, K=full(choice.K))


def adapted_controls(name: str, law: HipLaw) -> np.ndarray:
    """Indices of the controls the linear feedback ``name`` moves: those of
    :data:`~baslip.problem.study.ADAPTED_CONTROLS`, or all of ``law``'s."""
    return np.array([law.controls.index(n) for n in ADAPTED_CONTROLS.get(name, law.controls.names)])


def run_controllers(problem: Problem, study: Controllers, out_dir: Path, sources: Path, quiet: bool, lanes: int, workers: Workers) -> dict:
    """Stride-to-stride controllers on one gait, from the same perturbed starts, box by box."""
    from baslip.gait.from_problem import fixed_point_spec, solve_start, solver_for

    solver = solver_for(problem)
    gait = solve_start(problem, solver)
    if not gait.converged:
        raise StudyFailed(f"the gait did not converge: {gait.status} ({gait.message})")
    law = problem.hip_law
    A, B = solver.jacobian_map.jacobians(gait.X, gait.u, problem.params)
    spec = fixed_point_spec(problem)
    bounds = np.array([spec.bounds_of(n) for n in law.controls.names])
    context = {
        "X": gait.X, "u": gait.u, "params": problem.params, "law": law, "strides": study.strides,
        "tolerance": study.tolerance, "criterion": study.criterion, "horizon": study.horizon,
        "lower": bounds[:, 0], "upper": bounds[:, 1],
        "held": tuple(i for i, n in enumerate(law.controls.names) if n in problem.fix),
        "settle": any(m.trivial for m in gait.multipliers),
        "neutral": sum(m.trivial for m in gait.multipliers),
    }
    scale = control_scale(law)
    choices = {}
    for name in LINEAR:
        if name == "feedback" or name in study.controllers:  # feedback's choice is always reported
            try:
                choices[name] = feedback_for(study, context, A, B, scale, solver.jacobian_map,
                                             adapted_controls(name, law))
            except ValueError as err:
                raise StudyFailed(f"no linear {name} for this gait: {err}") from None
    context["gains"] = {name: choice.K for name, choice in choices.items()}
    table = study_table(out_dir / "controllers.csv", CONTROLLER_COLUMNS, ["controller", "box", "sample"], quiet)
    tasks = controller_tasks(study)
    lanes = max(1, min(lanes, len(tasks)))
    report = run_tasks([tasks[k::lanes] for k in range(lanes)], controllers_worker, context, table, problem.name,
                       quiet=quiet, workers=workers)
    rows = read_points(out_dir / "controllers.csv")
    basins = {name: _basin(rows, name, study.boxes) for name in study.controllers}
    smallest = [r for r in rows if r["box"] == min(study.boxes)]
    from baslip.viz import controllersplot  # drawn in this process only (see baslip.studies)

    controllersplot.controllers_figure(smallest, {n: w * min(study.boxes) for n, w in dict(study.perturbation).items()}, out_dir,
                               problem=problem_title(problem))
    controllersplot.basin_figure(basins, problem_title(problem), out_dir)
    return {
        "gait": {"hip_law": law.name, "apex": gait.apex, "control": gait.control,
                 "spectral_radius": gait.spectral_radius, "rank_dr_du": control_rank(B, scale)},
        **{name: _choice_summary(choice, law, A, B) for name, choice in choices.items()},
        "perturbation": dict(study.perturbation), "boxes": list(study.boxes), "tolerance": study.tolerance,
        "strides": study.strides, "resolve_criterion": study.criterion, "horizon": study.horizon,
        "controllers": {name: _tally([r for r in smallest if r["controller"] == name]) for name in study.controllers},
        "basins": basins,
        **run_info(report),
    }


def _choice_summary(choice: FeedbackChoice, law, A: np.ndarray, B: np.ndarray) -> dict:
    """A linear feedback's entry of result.json: its kind, gain and closed loop."""
    multipliers = closed_loop_multipliers(A, B, choice.K)
    return {"kind": choice.kind, "K": choice.K.tolist(), "rows": list(law.controls.names),
            "columns": list(APEX.names), "weight_exponents": list(choice.weights),
            "pilot_share": choice.pilot_share, "candidates": choice.candidates, "reason": choice.reason,
            "closed_loop_multipliers": [[float(m.real), float(m.imag)] for m in multipliers],
            "closed_loop_radius": choice.closed_loop_radius}


def _tally(mine: list[dict]) -> dict:
    """Outcome shares, median strides to converge and median cost of one controller's runs."""
    converged = [r for r in mine if r["outcome"] == "converged"]
    share = (lambda outcome: sum(r["outcome"] == outcome for r in mine) / len(mine)) if mine else (lambda _: None)
    return {
        "samples": len(mine),
        "basin_fraction": share("converged"),
        "settled_fraction": share("settled"),
        "bounded_fraction": share("bounded"),
        "fell_fraction": share("fell"),
        "median_strides_to_converge": float(np.median([r["strides_to_converge"] for r in converged])) if converged else None,
        "median_ms_per_stride": float(np.median([r["ms_per_stride"] for r in mine])) if mine else None,
    }


def _basin(rows: list[dict], name: str, boxes) -> dict:
    """Per box: the outcome shares, and the returned share with its 95 % interval; and the
    largest box whose returned share is at least :data:`BASIN_SHARE`."""
    per_box = []
    for box in boxes:
        mine = [r for r in rows if r["controller"] == name and r["box"] == box]
        returned = sum(r["outcome"] in RETURNED for r in mine)
        per_box.append({"box": box, **_tally(mine), "returned": returned,
                        "returned_fraction": returned / len(mine) if mine else None,
                        "ci95": list(wilson_interval(returned, len(mine)))})
    inside = [b["box"] for b in per_box if b["samples"] and b["returned"] >= BASIN_SHARE * b["samples"]]
    return {"per_box": per_box, "largest_90_box": max(inside) if inside else None}
