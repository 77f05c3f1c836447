"""Specification of baslip.engine.trajectory's continuous motion: what it holds and the physics
it must obey."""

import numpy as np
import pytest
from runs import ROOT

from baslip import ReturnMap, Tolerances, load_problem, solve_problem
from baslip.engine.trajectory import MOTION_COLUMNS, motion


@pytest.fixture(scope="module")
def downward():
    result = solve_problem(load_problem(ROOT / "problems" / "downward.yaml"))
    assert result.converged
    return result


@pytest.fixture(scope="module")
def hanging_motion(downward):
    return downward.trajectory(strides=2, samples=400)


def test_the_motion_has_every_column_and_the_four_phases(hanging_motion):
    assert set(hanging_motion.columns) == set(MOTION_COLUMNS)
    assert list(dict.fromkeys(hanging_motion["phase"])) == ["descent", "compression", "decompression", "ascent"]
    assert np.all(np.diff(hanging_motion["t"]) >= 0)
    assert set(hanging_motion["stride"]) == {0, 1}
    frame = hanging_motion.to_dataframe()
    assert str(frame["stride"].dtype) == "int64" and list(frame.columns) == list(MOTION_COLUMNS)


def test_work_of_the_hip_torque_equals_the_change_in_energy(hanging_motion):
    """In each stance phase the energy changes only by the hip motor's work; in flight it
    is constant; over a periodic stride both add up to nothing."""
    m = hanging_motion
    for stride in (0, 1):
        for phase in ("compression", "decompression"):
            at = np.where((m["stride"] == stride) & (m["phase"] == phase))[0]
            work = np.trapezoid(m["hip_power"][at], m["t"][at])
            change = m["energy"][at[-1]] - m["energy"][at[0]]
            assert abs(work) > 1e-3  # the torque does real work here
            assert change == pytest.approx(work, rel=3e-5)
        for phase in ("descent", "ascent"):
            at = (m["stride"] == stride) & (m["phase"] == phase)
            assert np.ptp(m["energy"][at]) < 1e-10
    assert m.work_of_torque() == pytest.approx(m["energy"][-1] - m["energy"][0], abs=2e-6)


def test_velocities_are_the_time_derivatives_of_the_positions(hanging_motion):
    m = hanging_motion
    at = np.where((m["stride"] == 0) & (m["phase"] == "decompression"))[0]
    t = m["t"][at]
    for position, velocity in (("z", "zdot"), ("y", "ydot"), ("hip_z", "hip_zdot"), ("theta_h", "theta_h_dot")):
        slope = np.gradient(m[position][at], t)
        assert np.max(np.abs(slope[2:-2] - m[velocity][at][2:-2])) < 1e-3 * np.max(np.abs(m[velocity][at])) + 1e-6


def test_the_ground_force_carries_the_weight_and_balances_the_massless_leg(hanging_motion, downward):
    """Over a periodic stride the ground's vertical impulse is the weight times the stride
    time and its horizontal impulse is nil (momentum). The force has the spring's push
    along the leg and the hip torque's reaction, torque / leg length, across it."""
    m, params = hanging_motion, downward.params
    one = m["stride"] == 0
    impulse_z = np.trapezoid(m["grf_z"][one], m["t"][one])
    assert impulse_z == pytest.approx(params.m * params.g * m["t"][one][-1], rel=1e-5)
    assert abs(np.trapezoid(m["grf_y"][one], m["t"][one])) < 1e-4 * impulse_z
    stance = one & np.isin(m["phase"], ("compression", "decompression"))
    along = np.array([-np.sin(m["leg_angle"][stance]), np.cos(m["leg_angle"][stance])])
    force = np.array([m["grf_y"][stance], m["grf_z"][stance]])
    spring = params.k * (params.rho0 - m["leg_length"][stance])
    assert np.allclose(np.sum(force * along, axis=0), spring, atol=1e-9)
    across = force - np.sum(force * along, axis=0) * along
    assert np.allclose(np.hypot(*across), np.abs(m["torque"][stance] / m["leg_length"][stance]), atol=1e-9)


def test_without_hip_torque_the_energy_is_conserved():
    result = solve_problem(load_problem(ROOT / "problems" / "continuation_slip_attack.yaml").replace(continuation=None))
    m = motion(ReturnMap(Tolerances(1e-10, 1e-10)), result.X, result.u, result.params, strides=1, samples=100)
    assert np.all(m["torque"] == 0.0)
    assert np.ptp(m["energy"]) < 1e-8 * m["energy"][0]


def test_the_motion_is_written_as_csv_with_units(hanging_motion):
    text = hanging_motion.csv_text().splitlines()
    assert text[0].startswith("t [s],stride,phase,y [m]") and "torque [N m]" in text[0]
    assert len(text) == len(hanging_motion) + 1
    assert text[1].split(",")[1:3] == ["0", "descent"]


@pytest.mark.parametrize("name", ["downward", "upward"])
def test_the_trunk_range_is_that_of_the_sampled_stride(name):
    """TrunkRange (flight phases by their ends, stance sampled) gives exactly the extremes of
    the sampled trajectory, whose flight is sampled too: in flight the trunk turns at a
    constant rate."""
    from baslip.engine.trajectory import TrunkRange, stride_trajectory

    gait = solve_problem(load_problem(ROOT / "problems" / f"{name}.yaml"))
    rmap = ReturnMap(Tolerances(1e-10, 1e-10))
    theta_h = stride_trajectory(rmap, gait.X, gait.u, gait.params, strides=1, samples=100).theta_h
    assert TrunkRange(rmap)(gait.X, gait.u, gait.params) == (float(theta_h.min()), float(theta_h.max()))
