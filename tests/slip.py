"""An independent SLIP: a point mass on a massless linear spring leg, written here without
any of baslip's code (Cartesian coordinates, RK4, the liftoff step bisected), for checking
baslip's SLIP limit (d = 0, no hip torque) against a second implementation.

The reference runner is that of Seyfarth et al. (2002, 2003): m = 80 kg, l0 = 1 m,
k = 20 kN/m, at the system energy of 5 m/s at a 1 m apex. Angles of attack are measured
from the horizontal (baslip's theta_td is measured from the vertical: 90 deg minus it).
"""

import math

import numpy as np

M, K, L0, G = 80.0, 20000.0, 1.0, 9.81
ENERGY = 0.5 * M * 5.0**2 + M * G * 1.0  # vx = 5 m/s at y = 1 m
#: Golden-section steps of :func:`least_excess`: the bracket shrinks to 0.618^40 of its width.
GOLDEN_STEPS = 40


def slip_apex_map(y_apex: float, attack_deg: float, h: float = 2e-5) -> float:
    """Next apex height [m] of the point-mass SLIP at ENERGY from apex height ``y_apex``
    [m], landing at ``attack_deg`` from the horizontal, in RK4 steps of ``h`` [s]."""
    sin_a, cos_a = math.sin(math.radians(attack_deg)), math.cos(math.radians(attack_deg))
    vx = math.sqrt(2 * (ENERGY - M * G * y_apex) / M)
    y_td = L0 * sin_a
    vy = -math.sqrt(2 * G * (y_apex - y_td))
    state = np.array([-L0 * cos_a, y_td, vx, vy])  # CoM relative to the foot

    def accel(s):
        r = s[:2]
        length = math.hypot(*r)
        return np.array([s[2], s[3], *(K / M * (L0 / length - 1.0) * r - np.array([0.0, G]))])

    def rk4(s, dt):
        k1 = accel(s)
        k2 = accel(s + dt / 2 * k1)
        k3 = accel(s + dt / 2 * k2)
        k4 = accel(s + dt * k3)
        return s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    compressed = False
    while True:
        nxt = rk4(state, h)
        length = math.hypot(*nxt[:2])
        compressed = compressed or length < L0 - 1e-9
        if compressed and length >= L0:
            lo, hi = 0.0, h  # bisect the step that crosses liftoff
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if math.hypot(*rk4(state, mid)[:2]) < L0 else (lo, mid)
            state = rk4(state, 0.5 * (lo + hi))
            break
        state = nxt
    return state[1] + state[3] ** 2 / (2 * G)


def slip_fixed_point(attack_deg: float, y0: float, h: float = 2e-5) -> tuple[float, float]:
    """A fixed point [m] of the apex map near ``y0`` (secant) and the map's slope there
    (central difference): the SLIP's one non-trivial multiplier."""
    f = lambda y: slip_apex_map(y, attack_deg, h) - y  # noqa: E731
    a, b = y0, y0 + 1e-3
    for _ in range(30):
        fa, fb = f(a), f(b)
        a, b = b, b - fb * (b - a) / (fb - fa)
        if abs(b - a) < 1e-11:
            break
    step = 1e-5
    slope = (slip_apex_map(b + step, attack_deg, h) - slip_apex_map(b - step, attack_deg, h)) / (2 * step)
    return b, slope


def least_excess(attack_deg: float, y_lo: float, y_hi: float, h: float = 1e-4) -> float:
    """The least of r(y) - y [m] over apex heights in [``y_lo``, ``y_hi``] (golden
    section: the excess must have one minimum there). Near the fold of the band's upper
    edge it is negative where two fixed points exist and positive where none does."""
    excess = lambda y: slip_apex_map(y, attack_deg, h) - y  # noqa: E731
    ratio = (math.sqrt(5) - 1) / 2
    a, b = y_lo, y_hi
    c, d = b - ratio * (b - a), a + ratio * (b - a)
    fc, fd = excess(c), excess(d)
    for _ in range(GOLDEN_STEPS):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - ratio * (b - a)
            fc = excess(c)
        else:
            a, c, fc = c, d, fd
            d = a + ratio * (b - a)
            fd = excess(d)
    return min(fc, fd)
