"""The generated pieces of a described stride: a chunk is its steps to the bit, the
carried Jacobian is the chain rule through them and the event's is the implicit-function
theorem's; compiled and in the virtual machine they are the same numbers."""

import math

import casadi as ca
import numpy as np
import pytest

from baslip.engine.dop853 import DOP853, step_function
from baslip.engine.hybrid_kernels import CHUNK, stride_functions, stride_kernels
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.catalogue.slip import SLIP
from baslip.model.symbolic import model_functions

STANCE = 1  # SLIP's stride: flight to touchdown, then stance to liftoff, then flight to the apex


@pytest.fixture(scope="module")
def slip():
    return model_functions(SLIP)


@pytest.fixture(scope="module")
def kernels(slip):
    return stride_kernels(slip)


@pytest.fixture(scope="module")
def theta(slip):
    return slip.theta({"m": 80.0, "k": 2e4, "l0": 1.0, "g": 9.81, "theta_td": math.radians(22.0)})


def touchdown_state() -> np.ndarray:
    """A stance start: leg length, its angle and their rates (rho, theta, rhodot, theta_dot)."""
    return np.array([1.0, -0.38, -1.2, 4.9])


def test_a_chunk_takes_the_steps_of_the_step_function_to_the_bit(slip, kernels, theta):
    step = step_function(slip.rhs["stance"], tableau=DOP853)
    falls, guard = slip.falls["stance"], slip.guards[STANCE]
    nodes, guards, fallen = kernels.phases[STANCE].chunk(touchdown_state(), 1e-3, theta)
    x = touchdown_state()
    for k in range(CHUNK):
        assert np.array_equal(np.array(falls(x, theta)).ravel(), fallen[:, k])
        x = np.array(step(x, 1e-3, theta)[0]).ravel()
        assert np.array_equal(x, nodes[:, k])
        assert float(guard(x, theta)) == guards[0, k]


def test_a_run_in_one_call_is_its_chunks_to_the_bit(kernels, theta):
    """A mode's run of 32 steps, one call, against four chunks of eight: the same nodes,
    guards, falls and carried Jacobians."""
    phase = kernels.phases[STANCE]
    rng = np.random.default_rng(11)
    carried = rng.standard_normal((4, 2 + len(theta)))
    run = phase.steps(32)[1](touchdown_state(), carried, 1e-3, theta)
    x, chained, pieces = touchdown_state(), carried, []
    for _ in range(4):
        piece = phase.chunk_sens(x, chained, 1e-3, theta)
        pieces.append(piece)
        x, chained = piece[0][:, -1], piece[1][:, -carried.shape[1]:]
    for whole, parts in zip(run, zip(*pieces)):
        assert np.array_equal(whole, np.hstack(parts))
    assert phase.steps(24) == (phase.chunk, phase.chunk_sens)  # no run of that count: chunks


def test_the_carried_jacobian_is_the_chain_rule_through_the_steps(slip, kernels, theta):
    x_sym, h, p = ca.SX.sym("x", 4), ca.SX.sym("h"), ca.SX.sym("theta", len(theta))
    x_next = step_function(slip.rhs["stance"], tableau=DOP853)(x_sym, h, p)[0]
    by_state = ca.Function("a", [x_sym, h, p], [ca.jacobian(x_next, x_sym), ca.jacobian(x_next, p)])
    rng = np.random.default_rng(7)
    carried = rng.standard_normal((4, 2 + len(theta)))  # d x / d(two section coordinates, theta)
    nodes, chained, _, _ = kernels.phases[STANCE].chunk_sens(touchdown_state(), carried, 1e-3, theta)
    x, expected = touchdown_state(), carried
    for k in range(CHUNK):
        a, b = (np.array(v) for v in by_state(x, 1e-3, theta))
        expected = a @ expected + np.hstack([np.zeros((4, 2)), b])
        x = nodes[:, k]
        width = expected.shape[1]
        np.testing.assert_allclose(chained[:, k * width:(k + 1) * width], expected, rtol=1e-13, atol=1e-13)


def test_the_events_jacobian_is_the_derivative_of_the_state_on_the_guard(slip, kernels, theta):
    """Central differences of (start -> the state where the guard is zero) along J's
    columns, the step's size re-solved each time."""
    phase = kernels.phases[STANCE]
    start = touchdown_state()
    nodes, at_nodes, _ = phase.chunk(start, 0.05, theta)  # stance ends within the chunk (0.4 s)
    guards = np.concatenate([[phase.guard(start, theta)[0].item()], at_nodes.ravel()])
    last = int(np.flatnonzero(guards[1:] >= 0)[0])
    x = start if last == 0 else nodes[:, last - 1]
    s = phase.event(x, 0.01, theta)[0].item()
    carried = np.hstack([np.eye(4)[:, :2], np.zeros((4, len(theta)))])
    analytic = phase.event_sens(x, carried, s, theta)[0]

    def on_guard(y):
        return phase.event(y, s, theta)[1].ravel()

    for column in range(2):
        shift = 1e-6 * carried[:, column]
        numeric = (on_guard(x + shift) - on_guard(x - shift)) / 2e-6
        np.testing.assert_allclose(analytic[:, column], numeric, rtol=1e-6, atol=1e-7)


def test_compiled_pieces_give_the_virtual_machines_numbers(slip, kernels, theta):
    machine = stride_kernels(slip, enabled=False)
    rng = np.random.default_rng(3)
    carried = rng.standard_normal((4, 2 + len(theta)))
    for compiled, interpreted in ((kernels.phases[STANCE], machine.phases[STANCE]),):
        for a, b in zip(compiled.chunk(touchdown_state(), 1e-3, theta),
                        interpreted.chunk(touchdown_state(), 1e-3, theta)):
            assert np.array_equal(a, b)
        for a, b in zip(compiled.chunk_sens(touchdown_state(), carried, 1e-3, theta),
                        interpreted.chunk_sens(touchdown_state(), carried, 1e-3, theta)):
            np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14)
        for a, b in zip(compiled.event(touchdown_state(), 0.01, theta),
                        interpreted.event(touchdown_state(), 0.01, theta)):
            assert np.array_equal(a, b)


def test_a_mode_with_a_closed_form_flow_is_stepped_along_it_and_the_others_by_dop853():
    """The BA-SLIP's flight gives its ballistic flow; its stance has none."""
    functions = model_functions(BA_SLIP, "pd")
    built = {f.name(): f for f in stride_functions(functions)}
    for i, mode in enumerate(BA_SLIP.order):
        called = {g.name() for name in (f"chunk_{i}", f"event_{i}") for g in built[name].find_functions()}
        stepped_by = {"flight_flow_step"} if mode == "flight" else {"DOP853_step"}
        assert stepped_by <= called and not ({"flight_flow_step", "DOP853_step"} - stepped_by) & called


def test_a_flows_steps_land_on_the_flow_at_their_summed_time():
    """Eight steps of 0.05 s along the flight's flow are the flow at 0.05 k s (the step
    hands the flow its size as the time, and theta as theta), to rounding."""
    functions = model_functions(BA_SLIP, "pd")
    theta = functions.theta({**{q.name: q.default for q in BA_SLIP.parameters},
                             **{q.name: q.default for q in BA_SLIP.controls_of("pd")}})
    start = np.array([0.0, 1.2, 0.3, 5.0, 0.5, -1.0])  # y, z, theta_h and their rates
    nodes, _, _ = stride_kernels(functions).phases[0].chunk(start, 0.05, theta)
    flow = functions.flows["flight"]
    for k in range(CHUNK):
        np.testing.assert_allclose(nodes[:, k], np.array(flow(start, theta, 0.05 * (k + 1))).ravel(),
                                   rtol=1e-14, atol=1e-14)
