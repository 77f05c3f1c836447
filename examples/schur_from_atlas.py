"""The stability NLP started from the gaits an atlas polished: does it find what the atlas
found? For every row of an atlas's ``atlas_best.csv`` the stability NLP (objective
``least_spectral_radius``) starts from the orbit nearest that gait; its status, its own
bound and its verified radius go beside the atlas's radius into ``crosscheck.csv`` and
``result.json`` of the output folder (written whole, at the end).

    python examples/schur_from_atlas.py results/atlas_upright problems/atlas_upright.yaml results/schur_from_atlas
"""

import csv
import io
import sys
import time
from dataclasses import replace
from pathlib import Path

from baslip.engine.codegen import recording_code
from baslip.files.atomic import json_text, write_files_atomically
from baslip.files.provenance import provenance
from baslip.gait.from_problem import fixed_point_spec, solver_for
from baslip.model.quantities import DESIGN
from baslip.problem.reader import load_problem, replace_problem

#: IPOPT's iterations for each run, as in problems/optimal_upright_schur.yaml.
MAX_ITER = 600
COLUMNS = ["ydot", "z", "meaning", "atlas_radius", "nlp_status", "nlp_iterations", "nlp_bound", "verified",
           "verified_radius", "reason", "time_s"]


def crosscheck(atlas: Path, problem_file: Path, solver=None) -> tuple[list[dict], dict]:
    """One row per polished gait of the atlas, and the run's provenance; ``solver``
    (default: the problem's, with :data:`MAX_ITER` iterations) runs the NLPs."""
    problem = load_problem(problem_file)
    problem = replace_problem(problem, solver=replace(problem.solver, max_iter=MAX_ITER))
    base = fixed_point_spec(problem)
    rows = []
    with recording_code() as code:
        solver = solver or solver_for(problem)
        with open(atlas / "atlas_best.csv", newline="") as handle:
            for best in csv.DictReader(handle):
                cell = {name: float(best[f"sweep_{name}"]) for name in ("ydot", "z")}
                gait = {name: float(best[name]) for name in DESIGN}
                spec = replace(base, fixed={**base.fixed, **cell}, objective="least_spectral_radius",
                               guess={n: v for n, v in gait.items() if n not in base.fixed and n not in cell})
                started = time.perf_counter()
                end = solver.solve(spec, problem.name)
                rows.append({**cell, "meaning": best["meaning"], "atlas_radius": float(best["spectral_radius"]),
                             "nlp_status": end.solver.return_status, "nlp_iterations": end.solver.iterations,
                             "nlp_bound": end.solver.spectral_bound, "verified": end.converged,
                             "verified_radius": end.spectral_radius if end.converged else None,
                             "reason": "" if end.converged else end.message,
                             "time_s": round(time.perf_counter() - started, 2)})
                print(" | ".join(str(rows[-1][c]) for c in COLUMNS), flush=True)
    return rows, provenance(problem, code)


def main(atlas: str, problem_file: str, out: str) -> None:
    rows, record = crosscheck(Path(atlas), Path(problem_file))
    table = io.StringIO()
    writer = csv.DictWriter(table, COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: ("" if v is None else v) for k, v in row.items()} for row in rows)
    summary = {"kind": "schur_from_atlas", "complete": True, "source": Path(atlas).name, "rows": rows,
               "provenance": record}
    folder = Path(out)
    write_files_atomically({folder / "crosscheck.csv": table.getvalue(), folder / "result.json": json_text(summary)})


if __name__ == "__main__":
    main(*sys.argv[1:4])
