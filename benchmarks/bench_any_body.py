"""Gaits from the body alone (issue 58's targets): how often, how stable, how fast.

Part 1, scaled bodies: bodies of the thesis's groups at random sizes (length x 0.1-10,
mass x 0.1-100, log-uniform), each asked for the shipped thesis gaits' cells carried to
it (downward: PD hanging; upward: PD upright; vpp: VPP), with no guess. A gait counts when
it is verified; its spectral radius is compared with the shipped gait's. Then, for the
first ``--families`` of those bodies, a families study (default budget) at the downward
cell carried to the body: its most stable gait against the thesis body's own families
study there (the same budget) and against the committed atlas's most stable gait there,
and its wall time.

Part 2, bodies of other proportions: groups drawn uniformly over a box (k rho0/(m g) in
[10, 40], I/(m rho0^2) in [0.03, 0.15], d/rho0 in [0, 0.25]) at human size (80 kg, 1 m),
at Froude numbers 0.3, 0.9 and 1.5, apex z = rho0 (0.98 + d/rho0) (the foot clears with
the leg 11 deg or more from vertical, upright or hanging), each under PD hanging, PD
upright and VPP (pivot 0.1 rho0 above the CoM), with no guess. Printed: the share with a
verified gait and with a stable one per law and posture, each failure's reason, timings.

Every solve is a new input (no memo); times are wall seconds in this process, the first
solve of each law (its set-up) reported apart.

    python benchmarks/bench_any_body.py [--bodies 50] [--families 10] [--seed 58] [--part 1|2]
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import statistics
import time
from pathlib import Path

import numpy as np

from baslip.api import families
from baslip.gait.fixedpoint import FixedPointSolver
from baslip.gait.from_problem import shooting_options, solve_problem
from baslip.gait.knowngaits import known_gaits
from baslip.model.dynamics import Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.similarity import Groups, body_with, carried, groups
from baslip.problem.reader import Problem
from baslip.status import Status

THESIS = Params()
HUMAN_SIZE = Params(m=80.0, I=4.58, k=20000.0, rho0=1.0, d=0.1, g=9.81)
FROUDE = (0.3, 0.9, 1.5)
#: (label, law, posture) of part 2.
KINDS = (("PD hanging", "pd", "hanging"), ("PD upright", "pd", "upright"), ("VPP", "vpp", "any"))


def solver_of(law: str, solvers: dict) -> FixedPointSolver:
    """One solver per law for the whole run (its set-up is paid once)."""
    if law not in solvers:
        solvers[law] = FixedPointSolver(shooting_options(Problem(name="x")), law=HIP_LAWS[law])
    return solvers[law]


def timed_solve(problem: Problem, solvers: dict):
    start = time.perf_counter()
    result = solve_problem(problem, solver_of(problem.hip_law.name, solvers), progress=False)
    return result, time.perf_counter() - start


def reason(result) -> str:
    """Why a solve gave no verified gait, in one line."""
    if result.diagnosis is not None and result.diagnosis.binding:
        return f"{result.message}; binding: {', '.join(limit.name for limit in result.diagnosis.binding[:3])}"
    return result.message


def scaled_bodies(count: int, rng, solvers: dict) -> list[Params]:
    print(f"Part 1: {count} bodies of the thesis's groups at random sizes, the shipped gaits' cells, no guess")
    shipped = [g for g in known_gaits() if g.groups.distance(groups(THESIS)) < 1e-12]
    reference = {g.name: _radius(g, solvers) for g in shipped}
    found, times, worst, bodies = 0, [], 0.0, []
    for _ in range(count):
        length, mass = math.exp(rng.uniform(math.log(0.1), math.log(10))), math.exp(rng.uniform(math.log(0.1), math.log(100)))
        body = body_with(groups(THESIS), size=Params(m=mass, rho0=0.2 * length, g=9.81))
        bodies.append(body)
        for gait in shipped:
            values = carried(gait.values, THESIS, body)
            fixed = {n: values[n] for n in ("z", "ydot", "r_vpp") if n in values}
            problem = Problem(name="scaled", params=body, hip_law=HIP_LAWS[gait.law], fix=fixed, posture=gait.posture)
            result, seconds = timed_solve(problem, solvers)
            times.append(seconds)
            if result.status == Status.CONVERGED:
                found += 1
                worst = max(worst, abs(result.spectral_radius - reference[gait.name]) / reference[gait.name])
    print(f"  verified gaits: {found} of {count * len(shipped)}; largest relative change of the spectral radius "
          f"against the shipped gait: {worst:.1e}; time a solve: median {statistics.median(times):.2f} s, "
          f"max {max(times):.2f} s; over 5 s: {sum(t > 5 for t in times)}")
    return bodies


def scaled_families(bodies: list[Params]) -> None:
    """The families study at the downward cell carried to each body, against the thesis
    body's own (the same budget)."""
    downward = next(g for g in known_gaits() if g.name == "downward")
    print(f"\n  families at the downward cell carried to the body, default budget ({len(bodies)} bodies + the thesis's):")
    thesis_best, _ = _best_of_families(THESIS, downward)
    print(f"    thesis body: most stable {thesis_best:.6g}")
    ratios, times = [], []
    for body in bodies:
        best, seconds = _best_of_families(body, downward)
        times.append(seconds)
        ratios.append(best / thesis_best if best is not None else math.inf)
        print(f"    m = {body.m:.3g} kg, rho0 = {body.rho0:.3g} m: most stable {best}, {seconds:.1f} s", flush=True)
    print(f"    at least as stable as the thesis body's (ratio <= 1 + 1e-6): {sum(r <= 1 + 1e-6 for r in ratios)} of "
          f"{len(ratios)}; ratio min {min(ratios):.6g}, max {max(ratios):.6g}; time a cell: median "
          f"{statistics.median(times):.1f} s, max {max(times):.1f} s")
    atlas = _committed_best("atlas_downward", downward)
    if atlas is not None:
        found = [r * thesis_best for r in ratios]
        print(f"    against the thesis body's most stable gait there in the committed atlas_downward ({atlas:.6g}; "
              f"24 seeds, 1,500 charts, 8 descents of 400 steps): at least as stable in "
              f"{sum(f <= atlas * (1 + 1e-6) for f in found)} of {len(found)}")


def _committed_best(name: str, gait) -> float | None:
    """The least polished radius of the committed atlas ``name`` at ``gait``'s cell."""
    path = Path(__file__).resolve().parents[1] / "results" / name / "result.json"
    if not path.is_file():
        return None
    best = [b["spectral_radius"] for b in json.loads(path.read_text())["best"]
            if math.isclose(b["ydot"], gait.values["ydot"]) and math.isclose(b["z"], gait.values["z"])]
    return min(best, default=None)


def _best_of_families(body: Params, gait) -> tuple[float | None, float]:
    """The least polished radius of a families study at ``gait``'s cell carried to ``body``
    (None if none), and its wall seconds."""
    values = carried(gait.values, THESIS, body)
    problem = Problem(name="scaled_families", params=body, hip_law=HIP_LAWS[gait.law], posture=gait.posture,
                      fix={"z": values["z"], "ydot": values["ydot"], "theta2_dot_des": 0.0})
    start = time.perf_counter()
    answer = families(problem, progress=False, jobs=1).record["answer"]
    seconds = time.perf_counter() - start
    return min((b["spectral_radius"] for b in answer["best"]), default=None), seconds


def _radius(gait, solvers: dict) -> float:
    problem = Problem(name=gait.name, params=THESIS, hip_law=HIP_LAWS[gait.law],
                      fix={n: gait.values[n] for n in ("z", "ydot", "r_vpp") if n in gait.values}, posture=gait.posture)
    result, seconds = timed_solve(problem, solvers)
    print(f"  {gait.name}: radius {result.spectral_radius:.6g} at the thesis body (first solve of its law: {seconds:.1f} s)")
    return result.spectral_radius


class StartOrigins(logging.Handler):
    """How each start from the body alone was found, read off baslip.gait.anybody's lines."""

    KINDS = ("carried over exactly", "continued", "seed", "default guess")

    def __init__(self):
        super().__init__(logging.INFO)
        self.counts = dict.fromkeys(self.KINDS, 0)

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        if not (text.startswith("start: the shipped gait") and "of the way" not in text
                or text.startswith("start: seed") or text.startswith("note: no start")):
            return
        kind = next(k for k in self.KINDS if k in text or (k == "default guess" and text.startswith("note")))
        self.counts[kind] += 1


def other_proportions(count: int, rng, solvers: dict) -> None:
    print(f"\nPart 2: {count} bodies of other proportions x Froude {FROUDE}, no guess")
    tally = {label: [0, 0, 0] for label, _, _ in KINDS}  # cells, verified, stable
    failures, times, origins = [], [], StartOrigins()
    starts = logging.getLogger("baslip.gait.anybody")
    starts.addHandler(origins)
    starts.setLevel(logging.INFO)  # its lines, though the solves hide progress
    for _ in range(count):
        body = body_with(Groups(rng.uniform(10, 40), rng.uniform(0.03, 0.15), rng.uniform(0.0, 0.25)), size=HUMAN_SIZE)
        for froude in FROUDE:
            ydot, z = math.sqrt(froude * body.g * body.rho0), body.rho0 * 0.98 + body.d
            for label, law, posture in KINDS:
                fixed = {"z": z, "ydot": ydot, **({"r_vpp": 0.1 * body.rho0} if law == "vpp" else {})}
                problem = Problem(name="other", params=body, hip_law=HIP_LAWS[law], fix=fixed, posture=posture)
                result, seconds = timed_solve(problem, solvers)
                print(f"    {label}, Froude {froude}: {result.status} in {seconds:.2f} s", flush=True)
                times.append(seconds)
                tally[label][0] += 1
                if result.status == Status.CONVERGED:
                    tally[label][1] += 1
                    tally[label][2] += bool(result.stability.stable)
                else:
                    g = groups(body)
                    failures.append(f"{label}, groups ({g.stiffness:.3g}, {g.inertia:.3g}, {g.offset:.3g}), "
                                    f"Froude {froude}: {reason(result)}")
    for label, (cells, verified, stable) in tally.items():
        print(f"  {label}: verified gait at {verified} of {cells} cells ({verified / cells:.0%}), stable at {stable}")
    print(f"  time a solve: median {statistics.median(times):.2f} s, max {max(times):.2f} s; "
          f"over 5 s: {sum(t > 5 for t in times)}")
    print("  starts: " + ", ".join(f"{kind} {number}" for kind, number in origins.counts.items()))
    print(f"  failures ({len(failures)}):")
    for line in failures:
        print(f"    {line}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, default=50)
    parser.add_argument("--families", type=int, default=10, help="bodies of part 1 given a families study")
    parser.add_argument("--seed", type=int, default=58)
    parser.add_argument("--part", type=int, choices=(1, 2), help="run only this part")
    args = parser.parse_args()
    rng, solvers = np.random.default_rng(args.seed), {}
    if args.part in (None, 1):
        bodies = scaled_bodies(args.bodies, rng, solvers)
        scaled_families(bodies[: args.families])
    if args.part in (None, 2):
        other_proportions(args.bodies, np.random.default_rng(args.seed + 1), solvers)


if __name__ == "__main__":
    main()
