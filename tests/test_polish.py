"""Specification of the Newton polish (:mod:`baslip.gait.polish`): from a point near the
manifold it lands on a fixed point of the compiled map (eps <= 1e-12); asked to stay
within the problem's bounds, it never takes a stride outside them, and says so when no
step inside them is left."""

import numpy as np
import pytest

from baslip import Params, ReturnMap, Tolerances
from baslip.gait.polish import POLISH_EPS, Polish, eps, within
from baslip.gait.shooting import FixedPointSpec

GAIT_X = np.array([0.4, -1.565727, 0.5, 0.164274])  # the shipped downward gait, to 6 digits
GAIT_U = np.array([-0.751879, 1.50002, -0.052462, 1.42038, 0.114713])


class Recorded(ReturnMap):
    """The compiled map, remembering the controls of every orbit it simulates."""

    def __init__(self):
        super().__init__(Tolerances(1e-12, 1e-12))
        self.controls: list[np.ndarray] = []

    def simulate(self, X, u, params, strides=1):
        self.controls.append(np.array(u, dtype=float))
        return super().simulate(X, u, params, strides)


@pytest.fixture
def recorded():
    return Recorded()


def spec_with(kp_bounds) -> FixedPointSpec:
    """The downward family at (0.5 m/s, 0.4 m), theta2_dot_des pinned, Kp within ``kp_bounds``."""
    return FixedPointSpec(Params(), fixed={"z": 0.4, "ydot": 0.5, "theta2_dot_des": 1.42038}, guess={},
                          bounds={"Kp": kp_bounds})


def test_the_polish_lands_on_a_fixed_point_of_the_compiled_map(recorded):
    X, u, iterations, note = Polish(recorded, recorded).run(spec_with((-100.0, 100.0)), GAIT_X + [0, 0, 0, 0.02], GAIT_U)
    assert note == "" and iterations >= 1
    assert eps(recorded.stride(X, u, Params()).apex, X) <= POLISH_EPS


def test_within_bounds_it_takes_no_stride_outside_them(recorded):
    """Kp held within 1e-4 N m/rad of the gait's: Gauss-Newton's first step from a start
    0.2 rad/s off in spin leaves that band, and is halved before any stride is taken there."""
    start_X, tight = GAIT_X + [0, 0, 0, 0.2], (GAIT_U[0] - 1e-4, GAIT_U[0] + 1e-4)
    Polish(recorded, recorded).run(spec_with(tight), start_X, GAIT_U)
    assert any(not tight[0] <= u[0] <= tight[1] for u in recorded.controls)  # the plain polish leaves it
    bounded = Recorded()
    X, u, _, note = Polish(bounded, bounded).run(spec_with(tight), start_X, GAIT_U, within_bounds=True)
    assert all(tight[0] <= c[0] <= tight[1] for c in bounded.controls)
    assert within(spec_with(tight), np.concatenate([X, u]))
    assert note in ("", " (polish stopped: no step within the bounds)")


def test_a_quantity_returned_a_hair_past_its_bound_is_put_on_it(recorded):
    """IPOPT returns a quantity it holds on a bound up to about 1e-8 past it. The free
    polish keeps it there (the verification would refuse it); the polish in bounds puts
    it on the bound and solves the rest of the point from there."""
    spec = spec_with((-100.0, GAIT_U[0] - 5e-8))
    free_X, free_u, _, _ = Polish(recorded, recorded).run(spec, GAIT_X, GAIT_U)
    assert not within(spec, np.concatenate([free_X, free_u]))
    X, u, _, note = Polish(recorded, recorded).run_in_bounds(spec, GAIT_X, GAIT_U)
    assert note == "" and u[0] == spec.bounds["Kp"][1]
    assert eps(recorded.stride(X, u, Params()).apex, X) <= POLISH_EPS


def test_a_step_that_would_leave_a_bound_holds_the_quantity_on_it(recorded):
    """Kp within 1e-4 N m/rad of the gait's and a start 0.2 rad/s off in spin: the free
    polish ends outside that band; in bounds, Kp is held on the edge it would cross and
    the family of fixed points is followed along it, to a fixed point of the compiled map."""
    start_X, tight = GAIT_X + [0, 0, 0, 0.2], (GAIT_U[0] - 1e-4, GAIT_U[0] + 1e-4)
    free_X, free_u, _, _ = Polish(recorded, recorded).run(spec_with(tight), start_X, GAIT_U)
    assert not within(spec_with(tight), np.concatenate([free_X, free_u]))
    X, u, _, note = Polish(recorded, recorded).run_in_bounds(spec_with(tight), start_X, GAIT_U)
    assert note == "" and u[0] in tight
    assert eps(recorded.stride(X, u, Params()).apex, X) <= POLISH_EPS
