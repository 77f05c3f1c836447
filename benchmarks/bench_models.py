"""Benchmark and cross-check of described models (issue 59).

    python benchmarks/bench_models.py [--sample N] [--repeats N]

Prints, in one process:

1. The generic engine's stride (value, and value with the exact Jacobian) on the SLIP,
   the guide's hopper and the BA-SLIP as a description, its generated code compiled and
   in CasADi's virtual machine, beside the BA-SLIP's own compiled engine on the same
   BA-SLIP strides: medians over ``--repeats`` calls at new points (each call perturbs
   the start, so no memo answers), and the time to build or load the generated code.
2. The BA-SLIP at each committed single gait: its description on the generic engine
   (at the steps :func:`calibrated_resolution` gives for the tolerance) against its own
   compiled engine, at 1e-10 and 1e-12, a stride and a stride with its Jacobians, medians
   of new starts.
3. A gait solve, a branch and an atlas of the hopper, timed.
4. BA-SLIP as a description against the compiled engine on a sample of ``--sample``
   points around the committed single gaits (each a random perturbation of a gait's apex
   and controls by up to 1 %): the largest difference of the stride and of its
   Jacobians, and how many strides either engine refused.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from baslip import ReturnMap, Tolerances
from baslip.analysis.atlas import AtlasSettings
from baslip.analysis.modelfamilies import continue_model, cover_model
from baslip.engine.hybrid import HybridMap, calibrated_resolution
from baslip.gait.modelsolver import ModelSolver
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.catalogue.slip import SLIP
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.symbolic import model_functions
from baslip.problem.model_file import load_model
from baslip.problem.modelspec import ModelSpec

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"


def committed_gaits() -> list[dict]:
    gaits = []
    for path in sorted(RESULTS.glob("*/result.json")):
        record = json.loads(path.read_text())
        if {"apex", "control", "params", "hip_law"} <= set(record) and \
                record.get("provenance", {}).get("problem", {}).get("strides", 1) == 1:
            gaits.append(record)
    return gaits


def median_ms(call, starts) -> float:
    times = []
    for start in starts:
        begin = time.perf_counter()
        call(start)
        times.append(time.perf_counter() - begin)
    return 1e3 * statistics.median(times)


def strides(repeats: int, rng: np.random.Generator) -> None:
    print("1. one stride, median of new starts [ms]; the set-up builds (or loads) the stride's generated code [s]")
    print(f"  {'model':<22}{'route':<18}{'set-up':>8}{'value':>10}{'value + Jacobian':>20}")
    hopper = load_model("models/hopper.py:HOPPER", ROOT / "problems")
    cases = [
        ("slip", SLIP, None, np.array([0.95, 5.1]), {"m": 80, "k": 2e4, "l0": 1, "g": 9.81, "theta_td": 0.384}),
        ("hopper", hopper, None, np.array([1.0, 5.0]), {**{q.name: q.default for q in hopper.parameters},
                                                         "theta_td": 0.39, "push": 0.0225}),
    ]
    gait = committed_gaits()[0]
    law = HIP_LAWS[gait["hip_law"]]
    X = np.array([gait["apex"][n] for n in APEX.names])
    cases.append(("ba-slip (" + gait["provenance"]["problem"]["name"] + ")", BA_SLIP, law.name, X,
                  {**gait["params"], **gait["control"]}))
    for name, model, law_name, x, values in cases:
        functions = model_functions(model, law_name)
        theta = functions.theta(values)
        starts = [x * (1 + 1e-4 * rng.standard_normal(len(x))) for _ in range(repeats)]
        for route, compiled in (("compiled C", True), ("virtual machine", False)):
            hybrid = HybridMap(functions, compiled=compiled)
            begin = time.perf_counter()
            _ = hybrid.kernels
            set_up = time.perf_counter() - begin
            resolution = calibrated_resolution(hybrid, x, theta, 1e-10)
            value = median_ms(lambda s: hybrid.stride(s, theta, resolution), starts)
            both = median_ms(lambda s: hybrid.stride(s, theta, resolution, jacobian=True), starts)
            print(f"  {name:<22}{route:<18}{set_up:>8.2f}{value:>10.2f}{both:>20.2f}   ({resolution.steps} steps a mode)")
    engine = ReturnMap(Tolerances(1e-10, 1e-10), law=law)
    params, u = Params(**gait["params"]), np.array([gait["control"][n] for n in law.controls.names])
    starts = [X * (1 + 1e-4 * rng.standard_normal(4)) for _ in range(repeats)]
    engine.stride(X, u, params)
    value = median_ms(lambda s: engine.stride(s, u, params), starts)
    both = median_ms(lambda s: engine.jacobians(s, u, params), starts)
    print(f"  {'ba-slip':<22}{'its own engine':<18}{'':>8}{value:>10.2f}{both:>20.2f}   (1e-10)")


def ba_slip_gaits(repeats: int, rng: np.random.Generator) -> None:
    maps = {law: HybridMap(model_functions(BA_SLIP, law)) for law in HIP_LAWS}
    for tolerance in (1e-10, 1e-12):
        print(f"2. the BA-SLIP at each committed gait: its description on the generic engine against its own engine, "
              f"median of new starts [ms], {tolerance:.0e}")
        print(f"  {'gait':<20}{'law':<6}{'steps':>6}{'described':>11}{'own':>7}{'ratio':>7}"
              f"{'described + J':>15}{'own + J':>9}{'ratio':>7}")
        for gait in committed_gaits():
            ba_slip_gait(gait, maps, tolerance, repeats, rng)


def ba_slip_gait(gait: dict, maps: dict, tolerance: float, repeats: int, rng: np.random.Generator) -> None:
    """One row of section 2: ``gait`` on both engines at ``tolerance``."""
    law = HIP_LAWS[gait["hip_law"]]
    X = np.array([gait["apex"][n] for n in APEX.names])
    hybrid = maps[law.name]
    theta = hybrid.functions.theta({**gait["params"], **gait["control"]})
    resolution = calibrated_resolution(hybrid, X, theta, tolerance)
    engine = ReturnMap(Tolerances(tolerance, tolerance), law=law)
    params, u = Params(**gait["params"]), np.array([gait["control"][n] for n in law.controls.names])
    engine.stride(X, u, params)
    starts = [X * (1 + 1e-4 * rng.standard_normal(4)) for _ in range(repeats)]
    described = median_ms(lambda s: hybrid.stride(s, theta, resolution), starts)
    own = median_ms(lambda s: engine.stride(s, u, params), starts)
    starts = [X * (1 + 1e-4 * rng.standard_normal(4)) for _ in range(repeats)]
    described_j = median_ms(lambda s: hybrid.stride(s, theta, resolution, jacobian=True), starts)
    own_j = median_ms(lambda s: engine.jacobians(s, u, params), starts)
    print(f"  {gait['provenance']['problem']['name']:<20}{law.name:<6}{resolution.steps:>6}{described:>11.2f}"
          f"{own:>7.2f}{described / own:>7.2f}{described_j:>15.2f}{own_j:>9.2f}{described_j / own_j:>7.2f}")


def families() -> None:
    print("3. the hopper's gait, branch and atlas [s]")
    hopper = load_model("models/hopper.py:HOPPER", ROOT / "problems")
    spec = ModelSpec(hopper, fixed={"z": 1.0, "ydot": 5.0}, guess={"theta_td": 0.38, "push": 0.01})
    begin = time.perf_counter()
    solver = ModelSolver(spec)
    built = time.perf_counter() - begin
    gait = solver.solve(spec)
    solved = time.perf_counter() - begin - built
    begin = time.perf_counter()
    branch = continue_model(solver, gait, "ydot", (3.0, 7.0))
    branched = time.perf_counter() - begin
    free = ModelSpec(hopper, fixed={"z": 1.0}, guess={"ydot": 5.0, "theta_td": 0.38, "push": 0.01},
                     bounds={"ydot": (2.0, 12.0)})
    gait_free = solver.solve(free)
    begin = time.perf_counter()
    _, charts = cover_model(solver, gait_free, AtlasSettings(max_charts=200))
    covered = time.perf_counter() - begin
    print(f"  functions built {built:.2f}; gait {solved:.2f} (verification {gait.verification:.1e}); "
          f"branch of {len(branch.points)} points {branched:.2f}; atlas of {len(charts)} charts {covered:.2f}")


def agreement(sample: int, rng: np.random.Generator) -> None:
    print(f"4. BA-SLIP as a description against the compiled engine, {sample} points near the committed gaits")
    gaits = committed_gaits()
    worst = {"stride": 0.0, "dX": 0.0, "du": 0.0}
    refused = {"generic": 0, "compiled": 0}
    compared = 0
    functions = {law: model_functions(BA_SLIP, law) for law in HIP_LAWS}
    maps = {law: HybridMap(f) for law, f in functions.items()}
    engines = {law: ReturnMap(Tolerances(1e-12, 1e-12), law=HIP_LAWS[law]) for law in HIP_LAWS}
    begin = time.perf_counter()
    for k in range(sample):
        gait = gaits[k % len(gaits)]
        law = HIP_LAWS[gait["hip_law"]]
        X = np.array([gait["apex"][n] for n in APEX.names]) * (1 + 0.01 * rng.uniform(-1, 1, 4))
        control = {n: v * (1 + 0.01 * rng.uniform(-1, 1)) for n, v in gait["control"].items()}
        u = np.array([control[n] for n in law.controls.names])
        params = Params(**gait["params"])
        theta = functions[law.name].theta({**gait["params"], **control})
        stride = engines[law.name].stride(X, u, params)
        if stride.apex is None:
            refused["compiled"] += 1
            continue
        hybrid = maps[law.name]
        outcome = hybrid.stride(X, theta, calibrated_resolution(hybrid, X, theta, 1e-12), jacobian=True)
        if not outcome.ok:
            refused["generic"] += 1
            continue
        dX, du = engines[law.name].jacobians(X, u, params)
        of_section, of_theta = outcome.jacobians()
        controls = [functions[law.name].theta_names.index(n) for n in law.controls.names]
        scale = max(1.0, float(np.max(np.abs(X))))
        worst["stride"] = max(worst["stride"], float(np.max(np.abs(outcome.end() - stride.apex))) / scale)
        worst["dX"] = max(worst["dX"], float(np.max(np.abs(of_section - dX))) / max(1.0, float(np.max(np.abs(dX)))))
        worst["du"] = max(worst["du"], float(np.max(np.abs(of_theta[:, controls] - du))) /
                          max(1.0, float(np.max(np.abs(du)))))
        compared += 1
    print(f"  compared {compared} strides in {time.perf_counter() - begin:.0f} s; refused by the compiled engine "
          f"{refused['compiled']}, by the generic one only {refused['generic']}")
    print(f"  largest difference, relative: stride {worst['stride']:.1e}, dr/dX {worst['dX']:.1e}, "
          f"dr/du {worst['du']:.1e}")


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(59)
    strides(args.repeats, rng)
    ba_slip_gaits(args.repeats, rng)
    families()
    agreement(args.sample, rng)


if __name__ == "__main__":
    main(sys.argv[1:])
