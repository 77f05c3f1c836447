"""Specification of baslip.gait.shooting: the multiple-shooting NLP whose functions are
compiled to C. Their derivatives are those of the functions themselves (checked against
central differences), and its solution is a fixed point of the exact map to the
accuracy of its RK4 intervals."""

import casadi as ca
import numpy as np
import pytest

from baslip import load_problem
from baslip.gait.from_problem import fixed_point_spec
from baslip.gait.shooting import ShootingNLP, ShootingOptions
from baslip.model.quantities import OBJECTIVES


@pytest.fixture(scope="module")
def downward_spec():
    return fixed_point_spec(load_problem("problems/downward.yaml"))


def lagrangian_gradient(functions, w, P, lam):
    grad_f = np.asarray(functions["nlp_grad_f"](w, P)[1]).ravel()
    jac_g = np.asarray(ca.densify(functions["nlp_jac_g"](w, P)[1]))
    return grad_f + jac_g.T @ lam


def test_compiled_derivatives_match_central_differences(solver, downward_spec):
    nlp = solver.nlp
    w = nlp.initial_guess(downward_spec, solver.residual_map)
    P = np.concatenate([downward_spec.params.vector(), downward_spec.start_design(), OBJECTIVES["min_torque"]])
    F = nlp.functions
    f0, g0 = (np.asarray(v).ravel() for v in F["nlp_fg"](w, P))
    jac = np.asarray(ca.densify(F["nlp_jac_g"](w, P)[1]))
    step = 1e-6
    for i in range(0, len(w), 11):
        e = np.zeros(len(w))
        e[i] = step
        g_plus, g_minus = (np.asarray(F["nlp_fg"](w + s * e, P)[1]).ravel() for s in (1, -1))
        assert np.max(np.abs((g_plus - g_minus) / (2 * step) - jac[:, i])) <= 1e-5 * max(1.0, np.max(np.abs(jac[:, i])))


def test_exact_hessian_matches_differences_of_the_lagrangian_gradient(downward_spec, solver):
    nlp = solver.nlp_for(1, exact=True)
    w = nlp.initial_guess(downward_spec, solver.residual_map)
    P = np.concatenate([downward_spec.params.vector(), downward_spec.start_design(), OBJECTIVES["nearest_guess"]])
    F = nlp.functions
    lam = np.random.default_rng(2).normal(size=F["nlp_fg"].size1_out(1))
    upper = np.asarray(ca.densify(F["nlp_hess_l"](w, P, 1.0, lam)))
    hessian = np.triu(upper) + np.triu(upper, 1).T
    step = 1e-6
    for i in range(0, len(w), 13):
        e = np.zeros(len(w))
        e[i] = step
        column = (lagrangian_gradient(F, w + e, P, lam) - lagrangian_gradient(F, w - e, P, lam)) / (2 * step)
        assert np.max(np.abs(column - hessian[:, i])) <= 1e-5 * max(1.0, np.max(np.abs(column)))


def test_nlp_solution_is_a_fixed_point_to_rk4_accuracy(solver, downward_spec):
    sol = solver.nlp.solve(downward_spec, rmap=solver.residual_map)
    assert sol.return_status == "Solve_Succeeded" and sol.iterations <= 10
    apex = solver.residual_map(sol.X, sol.u, downward_spec.params)
    assert np.linalg.norm(apex - sol.X) / np.linalg.norm(sol.X) <= 1e-5


def test_unknown_hessian_is_refused():
    with pytest.raises(ValueError, match="hessian"):
        ShootingNLP(ShootingOptions(hessian="newton"))


def test_a_warm_nlp_takes_its_sizes_and_bounds_from_beside_its_library_and_solves_the_same(solver, downward_spec,
                                                                                         monkeypatch):
    """With the library cached, the facts kept beside it replace the symbolic graph (which
    is then not built), and give the same bounds, sizes, row names and solution as the
    graph (the names explain a failure's binding rows)."""
    import baslip.gait.shooting as shooting

    monkeypatch.setattr(shooting, "read_facts", lambda *arguments, **keywords: None)
    from_graph = ShootingNLP()  # facts unread: the graph is built (and the facts written)
    monkeypatch.undo()
    monkeypatch.setattr(ShootingNLP, "_build", lambda self, compile: pytest.fail("the graph was built"))
    warm = ShootingNLP()
    for name in ("_n_w", "_n_orbit", "_periodicity_row", "_energy_row", "row_labels"):
        assert getattr(warm, name) == getattr(from_graph, name)
    np.testing.assert_array_equal(warm._lbg, from_graph._lbg)
    np.testing.assert_array_equal(warm._ubg, from_graph._ubg)
    a, b = (nlp.solve(downward_spec, rmap=solver.residual_map) for nlp in (from_graph, warm))
    assert a.return_status == b.return_status == "Solve_Succeeded"
    np.testing.assert_array_equal(a.w, b.w)


def test_facts_of_another_margin_are_not_taken(monkeypatch):
    """The constraints' bounds hold the transversality margin, which the library's name
    does not: an NLP of another margin builds its own graph."""
    ShootingNLP()  # the library and its facts are there
    built = []
    build = ShootingNLP._build
    monkeypatch.setattr(ShootingNLP, "_build", lambda self, compile: (built.append(1), build(self, compile))[1])
    other = ShootingNLP(ShootingOptions(margin=2e-3))
    assert built == [1] and other._ubg.min() == -2e-3
