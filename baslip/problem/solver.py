"""The ``solver:`` section of a problem: the NLP's discretisation and IPOPT's settings,
read and checked."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from baslip.errors import ProblemError
from baslip.problem.text import excerpt
from baslip.problem.values import mapping, number

#: Range of IPOPT's tolerance.
TOLERANCES = (1e-16, 1e-2)


@dataclass(frozen=True)
class SolverSettings:
    """Discretisation and IPOPT settings.

    Attributes
    ----------
    nodes : int
        Shooting intervals per stance phase (2 to 200).
    substeps : int
        RK4 steps per interval (1 to 20).
    max_iter : int
        IPOPT's iteration limit (1 to 100000).
    tol : float
        IPOPT's tolerance (1e-16 to 1e-2).
    print_level : int
        IPOPT's verbosity (0 to 12).
    """

    nodes: int = 20
    substeps: int = 1
    max_iter: int = 300
    tol: float = 1e-10
    print_level: int = 0


def parse_solver(value: Any) -> SolverSettings:
    """The ``solver:`` section ``value`` read and checked; raises :class:`ProblemError`
    naming the key."""
    raw = mapping(value, "solver", ("nodes", "substeps", "max_iter", "tol", "print_level"))
    limits = {"nodes": (2, 200), "substeps": (1, 20), "max_iter": (1, 100000), "print_level": (0, 12)}
    settings: dict[str, Any] = {}
    for name, v in raw.items():
        key = f"solver.{name}"
        if name == "tol":
            settings[name] = number(v, key)
            if not TOLERANCES[0] <= settings[name] <= TOLERANCES[1]:
                raise ProblemError(key, f"expected a tolerance in [{TOLERANCES[0]:g}, {TOLERANCES[1]:g}], got {settings[name]:g}")
            continue
        lo, hi = limits[name]
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ProblemError(key, f"expected an integer in [{lo}, {hi}], got {excerpt(v)}")
        settings[name] = v
    return SolverSettings(**settings)
