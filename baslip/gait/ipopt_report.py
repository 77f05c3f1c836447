"""What IPOPT did in a solve: each try and the report a result carries."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class IpoptTry:
    """One run of IPOPT: the settings that set it apart from the problem's, how it ended
    and its iterations."""

    settings: Mapping[str, object]
    return_status: str
    iterations: int

    def to_json_dict(self) -> dict:
        """``{settings, return_status, iterations}``, plain JSON types."""
        return {"settings": dict(self.settings), "return_status": self.return_status, "iterations": self.iterations}

    def text(self, number: int) -> str:
        """``try N (settings) status in K iterations``."""
        settings = ", ".join(f"{k} {v}" for k, v in self.settings.items())
        return f"try {number}{f' ({settings})' if settings else ''} {self.return_status} in {self.iterations} iterations"


@dataclass(frozen=True)
class SolverReport:
    """What IPOPT said, the wall time of the solve [s] and that of its set-up [s].

    Attributes
    ----------
    return_status : str
        IPOPT's return status (``Solve_Succeeded``, ...), or why IPOPT did not run.
    iterations : int
        IPOPT's iterations, over both tries when the exact-Hessian NLP had a second one.
    time_s : float
        Wall time [s] of the solve: NLP, polish, verification and stability, without the
        set-up of ``compile_s``.
    spectral_bound : float or None
        The stability NLP's bound on the multipliers (on its own discretisation;
        dimensionless), or None for other objectives.
    tries : tuple of IpoptTry
        Each run of IPOPT, in order: the settings that set it apart (the Hessian; the
        stability NLP's first quasi-Newton matrix), its return status and iterations.
        A second try runs, from the same start, only when the first fails.
    compile_s : float
        Wall time [s] of the set-up this solve waited for: code generation, gcc (on a
        first run) and loading the compiled libraries; the solver's own set-up is counted
        with its first solve (:mod:`baslip.engine.setuptime`).
    """

    return_status: str
    iterations: int
    time_s: float
    spectral_bound: float | None = None  # the stability NLP's bound on the multipliers (its own discretisation)
    tries: tuple[IpoptTry, ...] = ()
    compile_s: float = 0.0
