"""baslip: periodic running gaits of the Body-Attached SLIP and their stability.

Entry points: :func:`load_problem` and :func:`solve_problem` (or the command line
``baslip solve PROBLEM.yaml``, also ``python -m baslip.solve PROBLEM.yaml``),
:class:`ReturnMap` for the apex return map and multi-stride simulation, and
:class:`Params` / :class:`Control` for the numbers.
"""

from importlib import metadata as _metadata

try:
    __version__ = _metadata.version("baslip")
except _metadata.PackageNotFoundError:  # run from a source tree that is not installed
    __version__ = "unknown"

from .api import solve_problem
from .control import CONTROL, Control
from .fixedpoint import FixedPointResult, FixedPointSolver
from .model import APEX, Params, build_model
from .problem import Problem, ProblemError, load_problem, parse_problem
from .results import RunResults, open_results
from .returnmap import Fall, ReturnMap, Simulation, Stride, Tolerances
from .shipped import problems_dir

__all__ = [
    "APEX", "CONTROL", "Control", "Fall", "FixedPointResult", "FixedPointSolver", "Params",
    "Problem", "ProblemError", "ReturnMap", "RunResults", "Simulation", "Stride", "Tolerances", "build_model",
    "load_problem", "open_results", "parse_problem", "problems_dir", "solve_problem", "__version__",
]
