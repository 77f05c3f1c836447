"""The built-in model descriptions against what baslip knew before them.

* BA-SLIP as a description, through the generic engine, gives every committed single
  gait's stride, Jacobians and multipliers as the compiled engine does, and its own
  independent stride verifies each gait.
* The SLIP as a model of its own has the self-stable band of touchdown angles that
  baslip's SLIP limit of the BA-SLIP (d = 0, no torque) found: the committed
  ``continuation_slip_attack``'s period doubling and fold.
* The bipedal spring-mass walker walks with two stances a step and no flight: its
  reference walk is symmetric about mid-stance, re-verifies independently, and keeps its
  energy through single and double support.
"""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from slip import ENERGY

from baslip import ReturnMap, Tolerances
from baslip.analysis.modelfamilies import continue_model
from baslip.engine.hybrid import HybridMap, calibrated_resolution
from baslip.engine.hybrid_check import IndependentStride
from baslip.gait.modelsolver import ModelSolver
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.catalogue.slip import SLIP
from baslip.model.catalogue.walker import WALKER
from baslip.model.dynamics import APEX, Params
from baslip.model.hiplaw import HIP_LAWS
from baslip.model.symbolic import model_functions
from baslip.numerics.continuation import Settings
from baslip.problem.modelspec import ModelSpec

RESULTS = Path(__file__).resolve().parents[1] / "results"
#: Every committed result of one single-stride gait.
GAITS = sorted(p.parent.name for p in RESULTS.glob("*/result.json")
               if {"apex", "control", "params", "hip_law"} <= set(json.loads(p.read_text()))
               and json.loads(p.read_text()).get("provenance", {}).get("problem", {}).get("strides", 1) == 1)


@pytest.fixture(scope="module")
def described():
    return {law: model_functions(BA_SLIP, law) for law in HIP_LAWS}


def test_the_committed_gaits_are_many():
    assert len(GAITS) >= 10, GAITS


@pytest.mark.parametrize("name", GAITS)
def test_ba_slip_as_a_description_is_the_compiled_engines_ba_slip(described, name):
    result = json.loads((RESULTS / name / "result.json").read_text())
    law, params = HIP_LAWS[result["hip_law"]], Params(**result["params"])
    functions = described[law.name]
    X = np.array([result["apex"][n] for n in APEX.names])
    u = np.array([result["control"][n] for n in law.controls.names])
    theta = functions.theta({**result["params"], **result["control"]})
    hybrid = HybridMap(functions)
    resolution = calibrated_resolution(hybrid, X, theta, 1e-12)
    outcome = hybrid.stride(X, theta, resolution, jacobian=True)
    engine = ReturnMap(Tolerances(1e-12, 1e-12), law=law)
    dX, du = engine.jacobians(X, u, params)
    scale = max(1.0, float(np.max(np.abs(X))))
    assert np.max(np.abs(outcome.section - engine.stride(X, u, params).apex)) <= 1e-11 * scale
    controls = [functions.theta_names.index(n) for n in law.controls.names]
    assert np.max(np.abs(outcome.jacobian_section - dX)) <= 1e-8 * max(1.0, np.max(np.abs(dX)))
    assert np.max(np.abs(outcome.jacobian_theta[:, controls] - du)) <= 1e-8 * max(1.0, np.max(np.abs(du)))
    ours = np.sort_complex(np.linalg.eigvals(outcome.jacobian_section))
    committed = np.sort_complex(np.array([complex(*e) if isinstance(e, list) else complex(e["re"], e["im"])
                                          for e in result["eigenvalues"]]))
    assert ours == pytest.approx(committed, abs=1e-7)
    independent = IndependentStride(functions).stride(X, theta, resolution.scout)
    assert np.max(np.abs(independent - X)) <= 1e-10 * scale


def test_the_slips_self_stable_band_is_baslips_slip_limits():
    committed = json.loads((RESULTS / "continuation_slip_attack" / "result.json").read_text())
    edges = {p["type"]: p for p in committed["special_points"] if p["branch"] == 0}
    spec = ModelSpec(SLIP, fixed={"energy": ENERGY, "theta_td": math.radians(21.0)}, guess={"z": 0.94, "ydot": 5.1})
    solver = ModelSolver(spec)
    branch = continue_model(solver, solver.solve(spec), "theta_td", (math.radians(20.0), math.radians(25.0)),
                            Settings(step=0.05, max_step=0.2))
    found = {p.special: p for p in branch.points if p.special}
    for kind in ("period_doubling", "fold"):
        assert found[kind].values["theta_td"] == pytest.approx(edges[kind]["theta_td"], abs=1e-6)
        assert found[kind].values["z"] == pytest.approx(edges[kind]["apex"]["z"], abs=1e-6)
        assert found[kind].verification <= 1e-10
    stable = [p.values["theta_td"] for p in branch.points if p.spectral_radius < 1]
    assert edges["period_doubling"]["theta_td"] - 1e-6 <= min(stable) and max(stable) <= edges["fold"]["theta_td"] + 1e-6


@pytest.fixture(scope="module")
def walk():
    """The walker's reference walk: 820 J, 69 deg from the ground, 20 kN/m, solved from
    the reference's own values."""
    spec = ModelSpec(WALKER, fixed={"theta_td": WALKER.reference["theta_td"], "energy": 820.0},
                     guess={n: WALKER.reference[n] for n in ("rho", "rhodot", "theta_dot")})
    return ModelSolver(spec).solve(spec)


def test_the_walkers_reference_is_a_symmetric_verified_walk(walk):
    """Mid-stance of a symmetric walk has no leg speed, and its two single supports last
    as long; the independent stride confirms it to 1e-10."""
    first, double, last = walk.durations
    assert walk.verification <= 1e-10
    assert last == pytest.approx(first, rel=1e-9) and 0 < double < first
    assert abs(walk.values["rhodot"]) < 1e-9
    for name in ("rho", "theta_dot"):
        assert walk.values[name] == pytest.approx(WALKER.reference[name], rel=1e-9)


def _walker_energy(mode: str, x: np.ndarray, p: dict) -> float:
    """The walker's energy [J] in either mode, written here apart from the description."""
    m, k, l0, g = p["m"], p["k"], p["l0"], p["g"]
    if mode == "single":
        rho, theta, rhodot, theta_dot = x
        return 0.5 * m * (rhodot**2 + (rho * theta_dot) ** 2) + m * g * rho * math.cos(theta) + 0.5 * k * (rho - l0) ** 2
    x_, z, gap, x_dot, z_dot, _ = x
    rear, front = math.hypot(x_, z), math.hypot(x_ - gap, z)
    return 0.5 * m * (x_dot**2 + z_dot**2) + m * g * z + 0.5 * k * ((rear - l0) ** 2 + (front - l0) ** 2)


def test_the_walkers_energy_is_kept_through_single_and_double_support(walk):
    """At every step of every mode, to the integrator's tolerance (the map's is 1e-10)."""
    functions = model_functions(WALKER)
    section = np.array([walk.values[c] for c in WALKER.section.coordinates])
    theta = functions.theta(walk.values)
    outcome = HybridMap(functions).stride(section, theta, walk.resolution, nodes=True)
    energies = [_walker_energy(mode, state, walk.values) for mode, _, states in outcome.nodes for state in states]
    assert [mode for mode, *_ in outcome.nodes] == ["single", "double", "single"]
    assert len(energies) >= 3 * walk.resolution.steps
    assert max(abs(e - 820.0) for e in energies) < 1e-8 * 820.0


@pytest.mark.parametrize("attack_deg", [19.5, 22.5, 26.0])
def test_the_walkers_neimark_sacker_curve_bounds_its_stable_walks(attack_deg):
    """Two methods on one edge: near points of the committed Neimark-Sacker curve
    (results/walker, traced in landing angle and stiffness at 820 J), the walk solved 3 %
    softer is stable and 3 % stiffer unstable."""
    rows = [r for r in _csv_rows(RESULTS / "walker" / "curve.csv") if r["type"] == "neimark_sacker"]
    row = min(rows, key=lambda r: abs(math.degrees(float(r["theta_td"])) - attack_deg))
    assert float(row["verification"]) <= 1e-10
    radii = []
    for factor in (0.97, 1.03):
        spec = ModelSpec(WALKER, fixed={"theta_td": float(row["theta_td"]), "energy": 820.0,
                                        "k": factor * float(row["k"])},
                         guess={n: float(row[n]) for n in WALKER.section.coordinates})
        gait = ModelSolver(spec).solve(spec)
        assert gait.verification <= 1e-10 and abs(gait.values["rhodot"]) < 1e-9
        radii.append(gait.spectral_radius)
    assert radii[0] < 1 < radii[1]


def _csv_rows(path: Path) -> list[dict]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


def test_the_described_vpp_law_declares_its_family_and_its_gaits_radius_is_the_compiled_ones():
    """Under the VPP law (a torque of positions only) the upright gaits form a family at
    fixed controls: the description declares it, so the described solve flags the
    multiplier 1 as structural, and the human VPP gait's spectral radius is the committed
    compiled engine's (stable, 0.972)."""
    result = json.loads((RESULTS / "vpp_human" / "result.json").read_text())
    assert BA_SLIP.law("vpp").families == 1 and BA_SLIP.law("pd").families == 0
    free = ("theta_h", "theta_h_dot", "r_vpp", "theta_td")
    values = {**result["apex"], **result["control"]}
    spec = ModelSpec(BA_SLIP, law="vpp", fixed={**result["params"], "z": values["z"], "ydot": values["ydot"]},
                     guess={n: values[n] for n in free})
    gait = ModelSolver(spec).solve(spec)
    assert sum(gait.trivial) == 1
    assert gait.spectral_radius == pytest.approx(result["spectral_radius"], abs=1e-6) and gait.stable
