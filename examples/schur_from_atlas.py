"""The stability NLP started from the gaits an atlas polished: does it find what the atlas
found? For every row of an atlas's ``atlas_best.csv``, the stability NLP
(``objective: least_spectral_radius``) starts from the orbit nearest that gait, and its
verified radius is printed beside the atlas's.

    python examples/schur_from_atlas.py results/atlas_upright problems/atlas_upright.yaml
"""

import csv
import math
import sys
from dataclasses import replace

from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.gait.monodromy import STEP_RATE_LIMIT, step_rate
from baslip.model.quantities import DESIGN
from baslip.problem.reader import load_problem


def main(results: str, problem_file: str) -> None:
    problem = load_problem(problem_file)
    solver = solver_for(problem)
    base = fixed_point_spec(problem)
    steps = solver.options.nodes * solver.options.substeps
    print("cell (ydot, z) | meaning | atlas radius | h*rate at the start | NLP: status, bound | NLP verified radius")
    with open(f"{results}/atlas_best.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            cell = {name: float(row[f"sweep_{name}"]) for name in ("ydot", "z")}
            gait = {name: float(row[name]) for name in DESIGN}
            spec = replace(base, fixed={**base.fixed, **cell},
                           guess={n: v for n, v in gait.items() if n not in base.fixed and n not in cell},
                           objective="least_spectral_radius")
            rate = step_rate([gait[n] for n in ("Kp", "Kd", "theta2_des", "theta2_dot_des", "theta_td")],
                             problem.params.vector(), 0.5 * math.pi * math.sqrt(problem.params.m / problem.params.k) / steps)
            end = solver.solve(spec, problem.name)
            bound = end.solver.spectral_bound
            print(f"({cell['ydot']:g}, {cell['z']:g}) | {row['meaning']} | {float(row['spectral_radius']):.4g} | "
                  f"{rate:.2f}{' (beyond ' + str(STEP_RATE_LIMIT) + ')' if rate > STEP_RATE_LIMIT else ''} | "
                  f"{end.solver.return_status}, {'-' if bound is None else f'{bound:.4g}'} | "
                  f"{end.spectral_radius if end.converged else end.status.value + ': ' + end.message}", flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:3])
