"""The multiple-shooting NLP of one stride of a described model (the design card's shape).

Per mode: node states and a duration variable, one DOP853 step between consecutive nodes
(the mode's duration over the node count), the guard at zero at the mode's end and on its
own side of zero before it, the reset into the next mode, the falls at the nodes. The
stride starts on the section at the free and fixed section coordinates and returns to
them (less one per invariant, which returns it by itself), with any fixed invariant at its
value. The objective stays nearest the guess. IPOPT solves it from the first stride's
states.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from baslip.engine.dop853 import step_function
from baslip.engine.hybrid import Outcome
from baslip.errors import RunError
from baslip.model.symbolic import ModelFunctions
from baslip.problem.modelspec import ModelSpec


class NoShootingSolution(RunError):
    """IPOPT did not solve the shooting NLP; the message gives its status."""


class ModelShootingNLP:
    """The multiple-shooting NLP of one stride (see the module's docstring).

    Parameters
    ----------
    functions : ModelFunctions
        The model's symbolic pieces under its law.
    spec : ModelSpec
        What is fixed and free, the guess and the bounds.
    kept : list of int
        The section coordinates whose return the NLP asks for (one fewer per invariant).
    """

    def __init__(self, functions: ModelFunctions, spec: ModelSpec, kept: list[int]):
        self.f, self.spec, self.kept = functions, spec, kept
        self.steps = {mode: step_function(rhs) for mode, rhs in functions.rhs.items()}
        self.constraints: list[ca.MX] = []
        self.lower: list[np.ndarray] = []
        self.upper: list[np.ndarray] = []

    def _constrain(self, expr: ca.MX, low: float, high: float) -> None:
        self.constraints.append(expr)
        self.lower.append(np.full(expr.numel(), low))
        self.upper.append(np.full(expr.numel(), high))

    def solve(self, values: dict, first: Outcome) -> tuple[dict, str]:
        """The NLP's free quantities from the stride ``first`` at ``values``, and IPOPT's status."""
        spec, f = self.spec, self.f
        free = ca.MX.sym("free", len(spec.free))
        named = {**values, **dict(zip(spec.free, ca.vertsplit(free)))}
        theta = ca.vertcat(*[named[name] for name in f.theta_names])
        section = ca.vertcat(*[named[c] for c in spec.model.section.coordinates])
        start = f.lift(section)
        self._fix_invariants(start, theta)
        variables, starts, end = [free], [], start
        for number, (mode, trace) in enumerate(zip(spec.model.order, first.nodes)):
            entry = start if number == 0 else f.resets[number - 1](end, theta)
            block, initial, end = self._mode(number, mode, trace, entry, theta)
            variables += block
            starts += initial
        self._constrain(ca.vertcat(*[end[i] for i in f.section_index])[self.kept] - section[self.kept], 0.0, 0.0)
        guess = np.array([spec.guess[name] for name in spec.free])
        objective = ca.sumsqr((free - guess) / np.maximum(np.abs(guess), 1.0))
        return self._run(ca.vertcat(*variables), objective, np.concatenate([guess, *starts]), first, values)

    def _fix_invariants(self, start: ca.MX, theta: ca.MX) -> None:
        fixed = self.spec.fixed_invariants
        if fixed and self.f.invariants is not None:
            names = [i.name for i in self.spec.model.invariants_of(self.spec.law)]
            held = self.f.invariants(start, theta)
            for name, value in fixed.items():
                self._constrain(held[names.index(name)] - value, 0.0, 0.0)

    def _mode(self, number: int, mode: str, trace: tuple, entry: ca.MX, theta: ca.MX):
        """One mode's node states and duration, its constraints, their starting values
        (the first stride's, resampled), and its end state."""
        _, times, states = trace
        n, width = self.spec.nodes, self.f.rhs[mode].size1_in(0)
        guard = [*self.f.guards, self.f.section_guard][number]
        direction = [*self.f.directions, self.spec.model.section.direction][number]
        nodes, duration = ca.MX.sym(f"x{number}", width, n + 1), ca.MX.sym(f"T{number}")
        self._constrain(nodes[:, 0] - entry, 0.0, 0.0)
        for k in range(n):
            self._constrain(nodes[:, k + 1] - self.steps[mode](nodes[:, k], duration / n, theta)[0], 0.0, 0.0)
        self._constrain(guard(nodes[:, n], theta), 0.0, 0.0)
        for k in range(1, n):  # on the guard's own side until the end
            self._constrain(direction * guard(nodes[:, k], theta), -np.inf, 0.0)
        for k in range(n + 1):
            if mode in self.f.falls:
                self._constrain(self.f.falls[mode](nodes[:, k], theta), 0.0, np.inf)
        grid = np.linspace(0.0, times[-1], n + 1)
        resampled = np.column_stack([np.interp(grid, times, states[:, i]) for i in range(width)])
        return [ca.vec(nodes), duration], [resampled.ravel(), [times[-1]]], nodes[:, n]

    def _run(self, x: ca.MX, objective: ca.MX, x0: np.ndarray, first: Outcome, values: dict) -> tuple[dict, str]:
        spec = self.spec
        solver = ca.nlpsol("model_shooting", "ipopt", {"x": x, "f": objective, "g": ca.vertcat(*self.constraints)},
                           {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-12,
                                                            "max_iter": 500}})
        lower, upper = self._bounds(first)
        result = solver(x0=x0, lbx=lower, ubx=upper, lbg=np.concatenate(self.lower), ubg=np.concatenate(self.upper))
        status = str(solver.stats()["return_status"])
        if not solver.stats()["success"]:
            raise NoShootingSolution(f"the shooting NLP did not converge: IPOPT {status}")
        solution = np.array(result["x"]).ravel()[:len(spec.free)]
        return {**values, **dict(zip(spec.free, solution.tolist()))}, status

    def _bounds(self, first: Outcome) -> tuple[np.ndarray, np.ndarray]:
        """The free quantities' ranges; the node states are free, each duration positive."""
        spec, n = self.spec, self.spec.nodes
        lower = [spec.range_of(name)[0] for name in spec.free]
        upper = [spec.range_of(name)[1] for name in spec.free]
        for mode, duration in zip(spec.model.order, first.durations):
            width = self.f.rhs[mode].size1_in(0) * (n + 1)
            lower += [-np.inf] * width + [1e-3 * duration]
            upper += [np.inf] * width + [np.inf]
        return np.array(lower), np.array(upper)
