"""baslip: periodic running gaits of the Body-Attached SLIP and their stability.

Entry points: :func:`run` for whatever a problem holds (a gait, a study, a branch or a
curve), :func:`families` for which gaits exist at a problem's cell and the best one, :func:`load_problem` and :func:`solve_problem` for one gait (or the command
line ``baslip solve PROBLEM.yaml``, also ``python -m baslip.solve PROBLEM.yaml``),
:class:`ReturnMap` for the apex return map and multi-stride simulation, and
:class:`Params` / :class:`Control` for the numbers.

The names (``__version__`` too) are imported on first use, so that ``baslip --help``
and a worker's start do not load CasADi, or even the package metadata, before they
need it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Each public name and the module that defines it.
_HOMES = {
    "APEX": "baslip.model.dynamics", "Params": "baslip.model.dynamics", "build_model": "baslip.model.dynamics",
    "CONTROL": "baslip.model.hiplaw", "Control": "baslip.model.hiplaw",
    "Problem": "baslip.problem.reader", "load_problem": "baslip.problem.reader",
    "parse_problem": "baslip.problem.reader", "problems_dir": "baslip.problem.shipped",
    "ProblemError": "baslip.errors", "InputError": "baslip.errors", "RunError": "baslip.errors",
    "ProblemKindError": "baslip.errors",
    "Status": "baslip.status",
    "Fall": "baslip.engine.returnmap", "ReturnMap": "baslip.engine.returnmap", "Simulation": "baslip.engine.returnmap",
    "Stride": "baslip.engine.returnmap", "Tolerances": "baslip.engine.returnmap",
    "FixedPointResult": "baslip.gait.fixedpoint", "FixedPointSolver": "baslip.gait.fixedpoint",
    "solve_problem": "baslip.gait.from_problem",
    "RunResults": "baslip.results", "open_results": "baslip.results",
    "run": "baslip.api", "families": "baslip.api", "run_model": "baslip.api",
    "Model": "baslip.model.description", "ModelError": "baslip.model.description",
    "ModelSpec": "baslip.problem.modelspec", "ModelSolver": "baslip.gait.modelsolver",
    "ModelProblem": "baslip.problem.model_file", "ModelRun": "baslip.studies.modelruns",
    "__version__": "baslip.version",
}

__all__ = [
    "APEX",
    "CONTROL",
    "Control",
    "Fall",
    "FixedPointResult",
    "FixedPointSolver",
    "InputError",
    "Model",
    "ModelError",
    "ModelProblem",
    "ModelRun",
    "ModelSolver",
    "ModelSpec",
    "Params",
    "Problem",
    "ProblemError",
    "ProblemKindError",
    "ReturnMap",
    "RunError",
    "RunResults",
    "Simulation",
    "Status",
    "Stride",
    "Tolerances",
    "build_model",
    "families",
    "load_problem",
    "open_results",
    "parse_problem",
    "problems_dir",
    "run",
    "run_model",
    "solve_problem",
    "__version__",
]

if TYPE_CHECKING:  # the same names, for type checkers and editors
    from baslip.api import families, run, run_model
    from baslip.engine.returnmap import Fall, ReturnMap, Simulation, Stride, Tolerances
    from baslip.errors import InputError, ProblemError, ProblemKindError, RunError
    from baslip.gait.fixedpoint import FixedPointResult, FixedPointSolver
    from baslip.gait.from_problem import solve_problem
    from baslip.gait.modelsolver import ModelSolver
    from baslip.model.description import Model, ModelError
    from baslip.model.dynamics import APEX, Params, build_model
    from baslip.model.hiplaw import CONTROL, Control
    from baslip.problem.model_file import ModelProblem
    from baslip.problem.modelspec import ModelSpec
    from baslip.problem.reader import Problem, load_problem, parse_problem
    from baslip.problem.shipped import problems_dir
    from baslip.results import RunResults, open_results
    from baslip.status import Status
    from baslip.studies.modelruns import ModelRun
    from baslip.version import __version__


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'baslip' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
