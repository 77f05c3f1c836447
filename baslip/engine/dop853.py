"""Fixed-step explicit Runge-Kutta flows in CasADi, with embedded error estimates and
Newton-located events: the integration scheme of the compiled stride engine.

The scheme is generic in the ODE ``xdot = rhs(x, theta)``:

* :func:`step_function` is one step of an explicit tableau (by default Dormand and Prince's
  order-8 DOP853) as an SX Function of the state, the step size and ``theta``. It also
  returns the step's error estimate and the least value of some "watched" functions of the
  state over the step's stage points, so that a crossing between nodes is seen.
* :func:`chain` loops a step ``n`` times with ``mapaccum``, so the generated code holds one
  step and a loop instead of ``n`` inlined copies.
* :func:`event_step` ends a phase exactly on a guard: the last step's size solves
  ``guard(step(x, s)) = 0`` by Newton, unrolled in the graph, so that derivatives of the
  result with respect to ``x`` and ``theta`` are those of the implicit-function theorem.

Coefficients of DOP853: E. Hairer, S. P. Norsett, G. Wanner, *Solving Ordinary
Differential Equations I*, 2nd ed., Springer 1993, sec. II.10 (the 12-stage method of
order 8 with embedded estimators of orders 5 and 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True)
class Tableau:
    """Butcher tableau of an explicit Runge-Kutta method with two embedded estimators.

    ``a[i]`` holds the coefficients of stage ``i`` on the earlier stages; ``e5`` and ``e3``
    give the differences between the solution and the two lower-order solutions.
    """

    name: str
    order: int
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    c: tuple[float, ...]
    e5: tuple[float, ...]
    e3: tuple[float, ...]

    @property
    def stages(self) -> int:
        return len(self.b)


#: Dormand and Prince's order-8 method with its order-5 and order-3 estimators.
DOP853 = Tableau(
    name="DOP853",
    order=8,
    a=(
        (),
        (0.05260015195876773,),
        (0.0197250569845379, 0.0591751709536137),
        (0.02958758547680685, 0.0, 0.08876275643042054),
        (0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792),
        (0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242),
        (0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125),
        (0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402, 0.008273789163814023),
        (0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671, 20.154067550477894, -43.48988418106996),
        (0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193, 15.279233632882423, -33.28821096898486, -0.020331201708508627),
        (-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927, -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196),
        (2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188, 27.94888452941996, -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636),
    ),
    b=(0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034, 0.04471061572777259),
    c=(0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726, 0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0),
    e5=(0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502, 1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571, -0.022355307863886294),
    e3=(-0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, -0.4226823213237919, -0.1521609496625161, 0.20136540080403034, 0.02265179219836082),
)


def _weighted(coefficients, slopes):
    """Sum of coefficient * slope over the nonzero coefficients (no 0 * k terms in the graph)."""
    terms = [c * k for c, k in zip(coefficients, slopes) if c != 0.0]
    return sum(terms[1:], terms[0]) if terms else 0


def error_norm(err5, err3, scale):
    """Hairer's combined estimate of the order-8 local error from the order-5 and order-3
    differences (as in DOP853), in the RMS norm of ``err / scale``."""
    e5 = ca.sumsqr(err5 / scale)
    e3 = ca.sumsqr(err3 / scale)
    denominator = ca.sqrt((e5 + 0.01 * e3) * err5.numel())
    return ca.if_else(denominator > 0, e5 / ca.fmax(denominator, 1e-300), 0)


def step_function(
    rhs: ca.Function,
    watch: ca.Function | None = None,
    tableau: Tableau = DOP853,
) -> ca.Function:
    """One explicit step of ``tableau`` for ``xdot = rhs(x, theta)``, as an SX Function.

    Inputs ``x``, ``h`` [time], ``theta``; outputs ``x_next``, ``error`` (the local error
    estimate relative to the scale max(1, |x|)) and ``watch_min``, the least value of each
    entry of ``watch(x, theta)`` over the step's stage states and its end.
    """
    x = ca.SX.sym("x", rhs.size1_in(0))
    theta = ca.SX.sym("theta", rhs.size1_in(1))
    h = ca.SX.sym("h")
    slopes: list = []
    stage_states: list = []
    for row in tableau.a:
        stage = x + h * _weighted(row, slopes) if any(row) else x
        stage_states.append(stage)
        slopes.append(rhs(stage, theta))
    x_next = x + h * _weighted(tableau.b, slopes)
    scale = ca.fmax(1, ca.fmax(ca.fabs(x), ca.fabs(x_next)))
    error = error_norm(h * _weighted(tableau.e5, slopes), h * _weighted(tableau.e3, slopes), scale)
    outputs = [x_next, error]
    names = ["x_next", "error"]
    if watch is not None:
        watched = [watch(s, theta) for s in stage_states + [x_next]]
        least = watched[0]
        for w in watched[1:]:
            least = ca.fmin(least, w)
        outputs.append(least)
        names.append("watch_min")
    # At most four derivative directions per generated function: the stride's reverse
    # mode (four outputs) shares one adjoint of the step, while the generated C stays
    # compact; unbounded directions made gcc take about 60 s for each step count.
    return ca.Function(
        f"{tableau.name}_step", [x, h, theta], outputs, ["x", "h", "theta"], names, {"max_num_dir": 4}
    )


def chain(step: ca.Function, n: int) -> ca.Function:
    """``n`` steps of equal size from ``x0``: outputs the n node states (columns) and the
    per-step outputs of ``step`` (error estimates, watched minima), one column per step."""
    looped = step.mapaccum(f"{step.name()}_x{n}", n, [0], [0])
    x0 = ca.MX.sym("x0", step.size1_in(0))
    h = ca.MX.sym("h")
    theta = ca.MX.sym("theta", step.size1_in(2))
    outputs = looped(x0, ca.repmat(h, 1, n), ca.repmat(theta, 1, n))
    return ca.Function(
        f"{step.name()}_chain{n}", [x0, h, theta], list(outputs), ["x0", "h", "theta"],
        ["nodes"] + step.name_out()[1:],
    )


def event_step(step: ca.Function, rhs: ca.Function, guard: ca.Function, iterations: int) -> ca.Function:
    """The step from ``x`` whose size ``s`` puts ``guard(x_next, theta)`` at zero.

    Newton from the guess ``s0``, ``iterations`` times, unrolled in the graph. Its slope is
    the guard's rate along the flow, grad(guard) . rhs, which differs from the slope of the
    discrete step only by the step's local error: the iteration still converges to the
    root, and the derivative of its last iterate with respect to ``x`` and ``theta``
    converges to the implicit-function-theorem derivative at the same rate. The step is
    called, not inlined, so the generated code holds it once. Outputs ``s``, the state
    there, the guard value there (the residual), the last Newton update, and the step's
    other outputs.
    """
    x = ca.MX.sym("x", step.size1_in(0))
    theta = ca.MX.sym("theta", step.size1_in(2))
    s0 = ca.MX.sym("s0")
    guard_slope = _guard_slope(rhs, guard)
    s_prev, s = s0, s0
    for _ in range(iterations):
        x_end = step(x, s, theta)[0]
        s_prev, s = s, s - guard(x_end, theta) / guard_slope(x_end, theta)
    x_end, *rest = step(x, s, theta)
    return ca.Function(
        f"{step.name()}_to_{guard.name()}", [x, s0, theta],
        [s, x_end, guard(x_end, theta), s - s_prev, *rest],
        ["x", "s0", "theta"], ["s", "x_end", "residual", "last_update"] + step.name_out()[1:],
    )


def _guard_slope(rhs: ca.Function, guard: ca.Function) -> ca.Function:
    """d/dt guard(x(t), theta) = grad_x guard . rhs(x, theta), as an SX Function."""
    x = ca.SX.sym("x", rhs.size1_in(0))
    theta = ca.SX.sym("theta", rhs.size1_in(1))
    slope = ca.jtimes(guard(x, theta), x, rhs(x, theta))
    return ca.Function(f"{guard.name()}_rate", [x, theta], [slope])
