"""The SLIP limit of baslip against a published SLIP gait and an independent implementation.

With d = 0 and Kp = Kd = 0 the (z, ydot) part of the BA-SLIP is the classic SLIP apex map.
Reference gait: Seyfarth, Geyer & Herr (2003), "Swing-leg retraction: a simple control
model for stable running", J. Exp. Biol. 206:2547-2555, Fig. 6: m = 80 kg, l0 = 1 m,
k = 20 kN/m, system energy of vx = 5 m/s at y_apex = 1 m, angle of attack 68 deg from the
horizontal (theta_td = 22 deg from the vertical); its return map crosses the diagonal at a
stable fixed point (the model of Seyfarth et al. 2002, J. Biomech. 35:649-655). Rummel &
Seyfarth (2008), Int. J. Robot. Res. 27:919-934, give the tolerated range of landing
angle of this linear spring-mass model at 5 m/s as about 2 deg.

The published text gives the fixed point and its multiplier only graphically, so the
numbers are checked against a second, independent SLIP implementation (``tests/slip.py``:
Cartesian point mass, RK4, bisected liftoff), which shares no code with baslip.
"""

import math

import pytest
from slip import ENERGY, L0, G, K, M, slip_fixed_point

from baslip import Params
from baslip.gait.shooting import FixedPointSpec

SLIP = Params(m=M, I=10.0, k=K, rho0=L0, d=0.0, g=G)  # I is irrelevant: the trunk decouples


def baslip_slip_gait(solver, attack_deg: float):
    fixed = {
        "energy": ENERGY, "theta_td": math.radians(90.0 - attack_deg),
        "theta_h": math.pi / 2, "theta_h_dot": 0.0,
        "Kp": 0.0, "Kd": 0.0, "theta2_des": 0.0, "theta2_dot_des": 0.0,
    }
    return solver.solve(FixedPointSpec(SLIP, fixed=fixed, guess={"z": 0.95, "ydot": 5.0}))


@pytest.fixture(scope="module")
def gait_68(solver):
    return baslip_slip_gait(solver, 68.0)


def test_published_gait_is_a_verified_stable_fixed_point(gait_68):
    assert gait_68.status == "converged", gait_68.message
    assert gait_68.residual <= 1e-10
    assert gait_68.energy == pytest.approx(ENERGY, abs=1e-9)
    assert gait_68.stable  # Seyfarth et al. (2003), Fig. 6: a stable fixed point at 68 deg
    trivial = sorted(m.label for m in gait_68.stability.multipliers if m.trivial)
    assert trivial == ["energy", "spin", "spin"]
    for m in gait_68.stability.multipliers:
        if m.trivial:
            assert abs(m.value - 1.0) <= 1e-6


def test_fixed_point_and_multiplier_agree_with_an_independent_slip(gait_68):
    height, slope = slip_fixed_point(68.0, gait_68.apex["z"])
    (multiplier,) = [m.value for m in gait_68.stability.multipliers if not m.trivial]
    assert gait_68.apex["z"] == pytest.approx(height, abs=1e-7)
    assert multiplier.imag == 0.0
    assert multiplier.real == pytest.approx(slope, abs=1e-4)
    # Apex speed follows from the fixed energy.
    assert gait_68.apex["ydot"] == pytest.approx(math.sqrt(2 * (ENERGY - M * G * height) / M), abs=1e-7)


def test_self_stable_band_is_about_two_degrees_wide(solver):
    """Rummel & Seyfarth (2008): about 2 deg of tolerated landing angle at 5 m/s."""
    gaits = {a: baslip_slip_gait(solver, a) for a in (66.0, 66.5, 68.5, 69.0)}
    assert gaits[66.5].stable and gaits[68.5].stable
    # Past the band the gait exists but its multiplier has crossed -1 (period doubling).
    assert gaits[69.0].status == "converged" and not gaits[69.0].stable
    (multiplier,) = [m.value for m in gaits[69.0].stability.multipliers if not m.trivial]
    assert multiplier.real < -1.0
    # Below it the stable gait no longer exists (it has met the unstable one in a fold).
    assert gaits[66.0].status != "converged"
