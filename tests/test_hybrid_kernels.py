"""The generated pieces of a described stride: a chunk is its steps to the bit, the
adjoint sweep is the chain rule through them transposed and the event's adjoint the
implicit-function theorem's; compiled and in the virtual machine they are the same
numbers."""

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
    nodes, guards, fallen, at_start, _ = kernels.phases[STANCE].chunk(touchdown_state(), 1e-3, theta)
    assert float(guard(touchdown_state(), theta)) == at_start.item()
    x = touchdown_state()
    for k in range(CHUNK):
        assert np.array_equal(np.array(falls(x, theta)).ravel(), fallen[:, k])
        x = np.array(step(x, 1e-3, theta)[0]).ravel()
        assert np.array_equal(x, nodes[:, k])
        assert float(guard(x, theta)) == guards[0, k]


def test_a_run_in_one_call_is_its_chunks_to_the_bit(kernels, theta):
    """A mode's run of 32 steps, one call, against four chunks of eight: the same nodes,
    guards and falls."""
    phase = kernels.phases[STANCE]
    run = phase.steps(32)(touchdown_state(), 1e-3, theta)
    x, pieces = touchdown_state(), []
    for _ in range(4):
        piece = phase.chunk(x, 1e-3, theta)
        pieces.append(piece)
        x = piece[0][:, -1]
    for whole, parts in zip(run[:3], zip(*pieces)):  # nodes, guards, falls
        assert np.array_equal(whole, np.hstack(parts))
    assert run[4].item() == 32 and all(piece[4].item() == CHUNK for piece in pieces)  # none stopped
    assert phase.steps(24) is phase.chunk  # no run of that count: chunks


def first_stop(nodes, guards, falls, direction: int) -> int:
    """The first step that fell (a fall negative at its start), was lost (its end not
    finite) or crossed the guard in ``direction``, found in numpy; the length if none."""
    fell = np.any(falls < 0, axis=0)
    lost = ~np.all(np.isfinite(nodes), axis=0)
    g = direction * guards
    crossed = (g[1:] >= 0) & (g[:-1] < 0)
    stops = np.flatnonzero(fell | lost | crossed)
    return int(stops[0]) if len(stops) else nodes.shape[1]


def test_a_chunk_stops_at_the_first_step_that_fell_was_lost_or_crossed_the_guard(slip, kernels, theta):
    """Stance chunks from random touchdowns in steps from 1 ms (no event) to 0.3 s (the
    leg collapses or lifts off at once), and from a state that is not a number."""
    phase = kernels.phases[STANCE]
    direction = slip.directions[STANCE]
    rng = np.random.default_rng(13)
    found = set()
    starts = [touchdown_state() * (1 + 0.3 * rng.standard_normal(4)) for _ in range(40)]
    for start, h in zip([*starts, np.full(4, np.nan)], [*np.geomspace(1e-3, 0.3, 40), 1e-3]):
        nodes, guards, falls, at_start, stop = phase.steps(16)(start, h, theta)
        expected = first_stop(nodes, np.concatenate([at_start.ravel(), guards.ravel()]), falls, direction)
        assert stop.item() == expected
        found.add("none" if expected == 16 else "fell" if np.any(falls[:, expected] < 0)
                  else "lost" if not np.all(np.isfinite(nodes[:, expected])) else "crossed")
    assert found == {"none", "fell", "lost", "crossed"}  # every kind of stop was met


def stance_steps(slip, theta, count: int) -> np.ndarray:
    """The start states of ``count`` stance steps of 1 ms from the touchdown state (rows)."""
    step = step_function(slip.rhs["stance"], tableau=DOP853)
    states = [touchdown_state()]
    for _ in range(count - 1):
        states.append(np.array(step(states[-1], 1e-3, theta)[0]).ravel())
    return np.array(states)


def sweep(phase, adjoint, gathered, x, s, event, starts, width, theta):
    """One call of the adjoint kernel of ``width`` columns, ``starts`` (rows, last step
    first) filling the first of them, the others skipped."""
    columns = np.repeat(np.reshape(x, (-1, 1)), width, axis=1)
    columns[:, :len(starts)] = starts.T
    active = (np.arange(width) < len(starts)).astype(float)
    return phase.adjoints[width](adjoint, gathered, x, s, event, columns, active, 1e-3, theta)


def test_a_long_sweep_in_one_call_is_its_blocks_to_the_bit(slip, kernels, theta):
    """Back through 32 steps in one call, against four calls of eight (the event's step in
    the first only): the same adjoints."""
    phase = kernels.phases[STANCE]
    rng = np.random.default_rng(11)
    adjoint, gathered = rng.standard_normal((4, 2)), rng.standard_normal((len(theta), 2))
    starts = stance_steps(slip, theta, 33)[::-1]
    x_event, starts = starts[0], starts[1:]
    whole = sweep(phase, adjoint, gathered, x_event, 4e-4, 1.0, starts, 32, theta)
    event = 1.0
    for k in range(4):
        adjoint, gathered = sweep(phase, adjoint, gathered, x_event, 4e-4, event, starts[8 * k:8 * k + 8], 8, theta)
        event = 0.0
    assert np.array_equal(whole[0], adjoint) and np.array_equal(whole[1], gathered)


def test_the_adjoint_is_the_chain_rule_through_the_steps_transposed(slip, kernels, theta):
    """Five steps in a kernel of eight columns (three skipped, the event's step left out):
    A^T times the product of the steps' SX Jacobians, and G gathers each step's theta
    Jacobian, to rounding."""
    x_sym, h, p = ca.SX.sym("x", 4), ca.SX.sym("h"), ca.SX.sym("theta", len(theta))
    x_next = step_function(slip.rhs["stance"], tableau=DOP853)(x_sym, h, p)[0]
    by_state = ca.Function("a", [x_sym, h, p], [ca.jacobian(x_next, x_sym), ca.jacobian(x_next, p)])
    rng = np.random.default_rng(7)
    adjoint, gathered = rng.standard_normal((4, 2)), rng.standard_normal((len(theta), 2))
    starts = stance_steps(slip, theta, 5)[::-1]
    swept = sweep(kernels.phases[STANCE], adjoint, gathered, starts[0], 1e-3, 0.0, starts, 8, theta)
    for x in starts:  # the last step first
        a, b = (np.array(v) for v in by_state(x, 1e-3, theta))
        adjoint, gathered = a.T @ adjoint, gathered + b.T @ adjoint
    np.testing.assert_allclose(swept[0], adjoint, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(swept[1], gathered, rtol=1e-13, atol=1e-13)


def test_the_events_adjoint_is_the_derivative_of_the_state_on_the_guard(slip, kernels, theta):
    """Central differences of (start, theta -> the state where the guard is zero), the
    step's size re-solved each time, against the event's adjoint alone (no step swept)."""
    phase = kernels.phases[STANCE]
    start = touchdown_state()
    nodes, *_, last = phase.chunk(start, 0.05, theta)  # stance ends within the chunk (0.4 s)
    last = int(last.item())
    x = start if last == 0 else nodes[:, last - 1]
    s = phase.event(x, 0.01, theta)[0].item()
    adjoint = np.random.default_rng(5).standard_normal((4, 2))
    by_state, by_theta = sweep(phase, adjoint, np.zeros((len(theta), 2)), x, s, 1.0, np.empty((0, 4)), 8, theta)

    def on_guard(y, th):
        return phase.event(y, s, th)[1].ravel()

    for column in range(4):
        shift = 1e-6 * np.eye(4)[column]
        numeric = (on_guard(x + shift, theta) - on_guard(x - shift, theta)) / 2e-6
        np.testing.assert_allclose(by_state[column], adjoint.T @ numeric, rtol=1e-6, atol=1e-7)
    for column in range(len(theta)):
        shift = 1e-6 * max(1.0, abs(theta[column])) * np.eye(len(theta))[column]
        numeric = (on_guard(x, theta + shift) - on_guard(x, theta - shift)) / (2 * shift[column])
        np.testing.assert_allclose(by_theta[column], adjoint.T @ numeric, rtol=1e-6, atol=1e-7)


def test_compiled_pieces_give_the_virtual_machines_numbers(slip, kernels, theta):
    machine = stride_kernels(slip, enabled=False)
    rng = np.random.default_rng(3)
    adjoint, gathered = rng.standard_normal((4, 2)), rng.standard_normal((len(theta), 2))
    starts = stance_steps(slip, theta, 6)[::-1]
    compiled, interpreted = kernels.phases[STANCE], machine.phases[STANCE]
    for a, b in zip(compiled.chunk(touchdown_state(), 1e-3, theta), interpreted.chunk(touchdown_state(), 1e-3, theta)):
        assert np.array_equal(a, b)
    for a, b in zip(compiled.event(touchdown_state(), 0.01, theta), interpreted.event(touchdown_state(), 0.01, theta)):
        assert np.array_equal(a, b)
    for a, b in zip(sweep(compiled, adjoint, gathered, starts[0], 4e-4, 1.0, starts[1:], 8, theta),
                    sweep(interpreted, adjoint, gathered, starts[0], 4e-4, 1.0, starts[1:], 8, theta)):
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14)


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
    nodes, *_ = stride_kernels(functions).phases[0].chunk(start, 0.05, theta)
    flow = functions.flows["flight"]
    for k in range(CHUNK):
        np.testing.assert_allclose(nodes[:, k], np.array(flow(start, theta, 0.05 * (k + 1))).ravel(),
                                   rtol=1e-14, atol=1e-14)
