"""baslip: periodic running gaits of the Body-Attached SLIP and their stability.

Entry points: :func:`load_problem` and :func:`solve_problem` (or the command line
``python -m baslip.solve PROBLEM.yaml``), :class:`ReturnMap` for the apex return map and
multi-stride simulation, and :class:`Params` / :class:`Control` for the numbers.
"""

from .api import solve_problem
from .control import CONTROL, Control
from .fixedpoint import FixedPointResult, FixedPointSolver
from .model import APEX, Params, build_model
from .problem import Problem, ProblemError, load_problem, parse_problem
from .returnmap import Fall, ReturnMap, Simulation, Stride, Tolerances

__all__ = [
    "APEX", "CONTROL", "Control", "Fall", "FixedPointResult", "FixedPointSolver", "Params",
    "Problem", "ProblemError", "ReturnMap", "Simulation", "Stride", "Tolerances", "build_model",
    "load_problem", "parse_problem", "solve_problem",
]
