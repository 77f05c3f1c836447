"""A described model's body at another size: the factors of mass, length and time from
its defaults, exact where the body is similar, and how far it is where it is not."""

import math

import pytest

from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.catalogue.slip import SLIP
from baslip.model.sizes import similarity

#: A robot-sized SLIP of the human runner's groups: 2.5 kg on a 0.17 m leg.
SMALL = {"m": 2.5, "l0": 0.17, "k": 20000.0 * (2.5 / 80.0) / 0.17, "g": 9.81}


def test_the_similar_body_is_found_with_its_factors():
    scale = similarity(SLIP, SMALL)
    assert scale.distance < 1e-12
    assert (scale.mass, scale.length, scale.time) == pytest.approx((2.5 / 80.0, 0.17, math.sqrt(0.17)))


def test_a_quantitys_factor_is_the_product_of_its_dimensions_factors():
    scale = similarity(SLIP, SMALL)
    stiffness = scale.factor((1.0, 0.0, -2.0))  # N/m
    assert stiffness == pytest.approx(SMALL["k"] / 20000.0, rel=1e-12)
    assert scale.factor((0.0, 0.0, 0.0)) == 1.0


def test_a_body_of_other_groups_is_placed_at_the_nearest_similar_one_with_its_distance():
    """The human BA-SLIP (80 kg, I 4.58 kg m^2, leg 1 m, 20 kN/m, hip 0.1 m) has none of
    the thesis body's groups exactly: the factors still give its size, and the distance
    left says how far it is from any similar body."""
    human = {"m": 80.0, "I": 4.58, "k": 20000.0, "rho0": 1.0, "d": 0.1, "g": 9.81}
    scale = similarity(BA_SLIP, human)
    assert 0.1 < scale.distance < 1.0
    assert 40 < scale.mass < 160 and 2 < scale.length < 8
