"""The ``controllers`` study: three stride-to-stride controllers on one gait, compared.

The gait is the problem's fixed point. Apex states are drawn uniformly from the box
X* +- ``perturbation`` (four dimensions, seeded); from each, every controller runs for at
most ``strides`` strides (:func:`baslip.analysis.feedback.run_closed_loop`):

* ``constant``: the constant PD hip law, u = u*;
* ``feedback``: u = u* + K (X - X*), K deadbeat where dr/du has rank 4, else discrete LQR
  with Q = diag(1 / lqr_scale^2) and R = diag(1 / nominal control sizes^2);
* ``resolve``: u re-solved at every apex (``criterion``: thesis or tracking).

A run has *converged* once an apex is within ``tolerance`` (eq. 4.1) of X*; it is
*bounded* if it neither converged nor fell. The basin fraction of a controller is the
share of the box's samples that converge.
"""

from __future__ import annotations

import time

import numpy as np

from baslip.model.dynamics import APEX
from baslip.model.quantities import NOMINAL
from baslip.problem.study import Controllers

CONTROLLERS = ("constant", "feedback", "resolve")
CONTROLLER_COLUMNS = [
    "controller", "sample", *(f"d_{n}" for n in APEX.names), "outcome", "strides_run", "strides_to_converge",
    "final_eps", "max_residual", "ms_per_stride",
]


def controller_tasks(study: Controllers) -> list[dict]:
    """Every (controller, sample) with its perturbation; samples drawn once, shared."""
    rng = np.random.default_rng(study.seed)
    widths = dict(study.perturbation)
    deltas = rng.uniform(-1, 1, size=(study.samples, APEX.size)) * np.array([widths.get(n, 0.0) for n in APEX.names])
    return [
        {"controller": name, "sample": k, **{f"d_{n}": round(float(v), 15) for n, v in zip(APEX.names, delta)}}
        for name in CONTROLLERS for k, delta in enumerate(deltas)
    ]


def lqr_weights(study: Controllers) -> np.ndarray:
    """Q of the LQR: an apex deviation of lqr_scale (default: the nominal size) costs as
    much as a nominal change of a control."""
    scale = dict(study.lqr_scale)
    return np.diag([1 / scale.get(n, NOMINAL[n]) ** 2 for n in APEX.names])


def make_controller(name: str, context: dict, rmap):
    from baslip.analysis.feedback import ConstantControl, LinearFeedback, ResolvedControl

    X, u = context["X"], context["u"]
    if name == "constant":
        return ConstantControl(u)
    if name == "feedback":
        return LinearFeedback(X, u, context["K"], context["lower"], context["upper"])
    return ResolvedControl(rmap, context["params"], X, u, context["criterion"], fixed=context["held"],
                           lower=context["lower"], upper=context["upper"])


def controllers_worker(chunk: list[dict], context: dict, queue) -> None:
    """Worker process: run each task's controller from its perturbed apex."""
    from baslip.analysis.feedback import run_closed_loop
    from baslip.engine.returnmap import ReturnMap, Tolerances
    from baslip.gait.polish import eps

    try:
        rmap = ReturnMap(Tolerances(1e-12, 1e-12))
        for task in chunk:
            if task.get("done"):
                continue
            X0 = context["X"] + np.array([task[f"d_{n}"] for n in APEX.names])
            controller = make_controller(task["controller"], context, rmap)
            started = time.perf_counter()
            run = run_closed_loop(rmap, context["params"], controller, X0, context["X"], context["strides"],
                                  context["tolerance"])
            elapsed = time.perf_counter() - started
            queue.put({
                **task, "outcome": run.outcome, "strides_run": len(run.controls),
                "strides_to_converge": run.strides_to_converge,
                "final_eps": eps(run.apexes[-1], context["X"]),
                "max_residual": float(np.max(run.residuals)) if len(run.residuals) else 0.0,
                "ms_per_stride": 1e3 * elapsed / max(len(run.controls), 1),
            })
    finally:
        queue.put(None)
