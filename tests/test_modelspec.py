"""What to solve for a described model: each quantity fixed or free, checked as it is built."""

import pytest

from baslip.errors import ArgumentError
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.catalogue.slip import SLIP
from baslip.model.sizes import similarity
from baslip.problem.modelspec import ModelSpec

#: The human-sized BA-SLIP body.
HUMAN = {"m": 80.0, "I": 4.58, "k": 20000.0, "rho0": 1.0, "d": 0.1, "g": 9.81}


def test_quantities_left_out_keep_their_defaults_and_are_fixed():
    spec = ModelSpec(SLIP, fixed={"z": 1.0}, guess={"ydot": 5.0, "theta_td": 0.4})
    assert spec.free == ("ydot", "theta_td")
    assert spec.values() == {"theta_td": 0.4, "m": 80.0, "k": 20000.0, "l0": 1.0, "g": 9.81, "z": 1.0, "ydot": 5.0}


def test_an_invariant_may_be_fixed_and_is_no_quantity():
    spec = ModelSpec(SLIP, fixed={"energy": 1784.8, "theta_td": 0.38}, guess={"z": 0.95, "ydot": 5.0})
    assert spec.fixed_invariants == {"energy": 1784.8}
    assert "energy" not in spec.values()


@pytest.mark.parametrize("kwargs, message", [
    ({"fixed": {"zz": 1.0}, "guess": {"z": 1, "ydot": 5}}, r"fixed\.zz: is not a quantity of model slip"),
    ({"fixed": {"z": 1.0}, "guess": {"z": 1, "ydot": 5}}, r"z: is both fixed and guessed"),
    ({"fixed": {"z": 1.0}}, r"ydot: is a section coordinate: fix it or guess it"),
    ({"fixed": {"z": float("nan")}, "guess": {"ydot": 5}}, r"z: must be a finite number"),
    ({"fixed": {"z": 1.0}, "guess": {"ydot": 5}, "nodes": 1}, r"nodes: must be an integer of at least 2"),
    ({"fixed": {"z": 1.0}, "guess": {"ydot": 5}, "tolerance": 0.1}, r"tolerance: must lie in"),
    ({"fixed": {"z": 1.0}, "guess": {"ydot": 5}, "bounds": {"energy": (0, 1)}}, r"bounds\.energy: is not a quantity"),
])
def test_a_bad_spec_is_refused_naming_the_entry(kwargs, message):
    with pytest.raises(ArgumentError, match=message):
        ModelSpec(SLIP, **kwargs)


def test_a_range_is_the_quantitys_own_within_the_specs_bounds():
    spec = ModelSpec(SLIP, fixed={"z": 1.0}, guess={"ydot": 5.0, "theta_td": 0.4}, bounds={"theta_td": (0.2, 3.0)})
    assert spec.range_of("theta_td") == (0.2, pytest.approx(1.5707963267948966))
    assert spec.range_of("ydot") == (-float("inf"), float("inf"))


def test_a_value_outside_its_range_is_refused():
    with pytest.raises(ArgumentError, match=r"^fixed\.theta_td: 2 lies outside its range"):
        ModelSpec(SLIP, fixed={"z": 1.0, "theta_td": 2.0}, guess={"ydot": 5.0})
    with pytest.raises(ArgumentError, match=r"^fixed\.m: -1 lies outside its range"):
        ModelSpec(SLIP, fixed={"z": 1.0, "m": -1.0}, guess={"ydot": 5.0})


def test_a_controls_range_scales_with_the_body():
    """A control's range is given at the model's default body; at the human body the PD
    gains' ranges are as many times wider as a torque per radian (per radian a second)
    is larger there, and an angle's range stays as it is."""
    thesis = ModelSpec(BA_SLIP, law="pd", fixed={"z": 0.4, "ydot": 0.5}, guess={"theta_h": 1.5, "theta_h_dot": 0.0})
    human = ModelSpec(BA_SLIP, law="pd", fixed={**HUMAN, "z": 1.06, "ydot": 3.0},
                      guess={"theta_h": 1.5, "theta_h_dot": 0.0})
    scale = similarity(BA_SLIP, HUMAN)
    for gain in ("Kp", "Kd"):
        factor = scale.factor(BA_SLIP.dimension(gain, "pd"))
        assert factor > 100
        assert human.range_of(gain) == pytest.approx(tuple(v * factor for v in thesis.range_of(gain)))
    assert human.range_of("theta_td") == thesis.range_of("theta_td")


def test_a_human_sized_gain_is_accepted_and_a_wild_one_refused():
    ModelSpec(BA_SLIP, law="pd", fixed={**HUMAN, "z": 1.06, "ydot": 3.0, "Kd": 1338.0},
              guess={"theta_h": 1.5, "theta_h_dot": 0.0})
    with pytest.raises(ArgumentError, match=r"^fixed\.Kd: .* lies outside its range"):
        ModelSpec(BA_SLIP, law="pd", fixed={**HUMAN, "z": 1.06, "ydot": 3.0, "Kd": 1e9},
                  guess={"theta_h": 1.5, "theta_h_dot": 0.0})
