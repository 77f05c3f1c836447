"""The functions of the periodic-stride NLP that its library compiles: objective and
constraints, their first derivatives and a Hessian (see :mod:`baslip.gait.shooting`)."""

from __future__ import annotations

import casadi as ca

#: The names of the NLP's compiled functions, in the order :func:`nlp_functions` makes them.
NLP_FUNCTIONS = ("nlp_fg", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")


def nlp_functions(w, params, weights, distance, effort, bound, g, kind: str) -> list[ca.Function]:
    """The NLP's objective and constraints, their first derivatives, and the Hessian that
    :data:`~baslip.gait.shooting.HESSIANS` names by ``kind`` (for ``limited-memory`` it is built but unused).
    ``bound`` is the stability NLP's bound on the multipliers (0 elsewhere), minimised
    with weight 1."""
    f = weights[0] * distance + weights[1] * ca.sumsqr(effort) + bound
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())
    if kind == "exact":
        hessian = ca.hessian(lam_f * f + ca.dot(lam_g, g), w)[0]
    else:  # exact for the distance term, Gauss-Newton (2 J^T J) for the torque term
        effort_jacobian = ca.jacobian(effort, w)
        hessian = lam_f * (weights[0] * ca.hessian(distance, w)[0]
                           + 2 * weights[1] * ca.mtimes(effort_jacobian.T, effort_jacobian))
    return [
        ca.Function("nlp_fg", [w, params], [f, g], ["x", "p"], ["f", "g"]),
        ca.Function("nlp_grad_f", [w, params], [f, ca.gradient(f, w)], ["x", "p"], ["f", "grad_f_x"]),
        ca.Function("nlp_jac_g", [w, params], [g, ca.jacobian(g, w)], ["x", "p"], ["g", "jac_g_x"]),
        ca.Function("nlp_hess_l", [w, params, lam_f, lam_g], [ca.triu(hessian)],
                    ["x", "p", "lam_f", "lam_g"], ["hess_gamma_x_x"]),
    ]
