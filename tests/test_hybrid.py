"""The stride of a described model: its map against an independent SLIP, its Jacobian
against finite differences, its energy conserved, its falls and guards named."""

import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from slip import ENERGY, slip_apex_map

from baslip.engine.hybrid import HybridMap, Resolution, calibrated_resolution
from baslip.engine.hybrid_check import IndependentStride
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.catalogue.slip import SLIP
from baslip.model.dynamics import APEX
from baslip.model.symbolic import model_functions

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "problems" / "models"))
from hopper import HOPPER  # noqa: E402

FINE = Resolution(0.01, 32)


@pytest.fixture(scope="module")
def slip():
    return model_functions(SLIP)


def theta(slip, attack_deg=68.0):
    return slip.theta({"m": 80.0, "k": 2e4, "l0": 1.0, "g": 9.81, "theta_td": math.radians(90.0 - attack_deg)})


def apex_speed(z):
    return math.sqrt(2 * (ENERGY - 80.0 * 9.81 * z) / 80.0)


@pytest.mark.parametrize("z", [0.95, 1.0, 1.05])
def test_the_slip_map_is_the_independent_slips(slip, z):
    """tests/slip.py shares no code with baslip: Cartesian coordinates, RK4 at 2e-5 s."""
    outcome = HybridMap(slip).stride(np.array([z, apex_speed(z)]), theta(slip), FINE)
    assert outcome.section[0] == pytest.approx(slip_apex_map(z, 68.0), abs=1e-9)


def test_energy_is_conserved_along_the_slip_stride(slip):
    outcome = HybridMap(slip).stride(np.array([0.95, apex_speed(0.95)]), theta(slip), FINE)
    z, ydot = outcome.section
    assert 0.5 * 80.0 * ydot**2 + 80.0 * 9.81 * z == pytest.approx(ENERGY, rel=1e-13)


def test_the_jacobian_is_the_derivative_of_the_map(slip):
    hybrid, x, th = HybridMap(slip), np.array([0.95, 5.1]), theta(slip)
    outcome = hybrid.stride(x, th, FINE, jacobian=True)
    for i in range(2):
        step = np.zeros(2)
        step[i] = 1e-6
        central = (hybrid.stride(x + step, th, FINE).section - hybrid.stride(x - step, th, FINE).section) / 2e-6
        assert outcome.jacobian_section[:, i] == pytest.approx(central, abs=1e-7)
    for j in range(len(th)):
        step = np.zeros(len(th))
        step[j] = 1e-6 * max(1.0, abs(th[j]))
        central = (hybrid.stride(x, th + step, FINE).section - hybrid.stride(x, th - step, FINE).section) / (2 * step[j])
        assert outcome.jacobian_theta[:, j] == pytest.approx(central, rel=1e-5, abs=1e-7)


def test_the_calibrated_resolution_agrees_with_the_independent_stride(slip):
    x, th = np.array([0.95, 5.1]), theta(slip)
    hybrid = HybridMap(slip)
    resolution = calibrated_resolution(hybrid, x, th, 1e-12)
    independent = IndependentStride(slip).stride(x, th, resolution.scout)
    assert np.max(np.abs(hybrid.stride(x, th, resolution).section - independent)) < 1e-11


def test_at_its_rounding_the_calibration_returns_its_most_accurate_count():
    """The BA-SLIP's upward gait asked for 1e-12: the strides' differences between n and
    2n steps reach their rounding and then grow with the steps, so no count agrees to a
    tenth of the tolerance. The calibration returns the count with the least difference,
    not the most steps it may try (256, whose stride is further off)."""
    result = json.loads((Path(__file__).resolve().parents[1] / "results" / "upward" / "result.json").read_text())
    functions = model_functions(BA_SLIP, result["hip_law"])
    X = np.array([result["apex"][n] for n in APEX.names])
    th = functions.theta({**result["params"], **result["control"]})
    hybrid = HybridMap(functions)
    chosen = calibrated_resolution(hybrid, X, th, 1e-12)
    ends = {n: hybrid.stride(X, th, Resolution(chosen.scout, n)).end() for n in (8, 16, 32, 64, 128, 256, 512)}
    differences = {n: float(np.max(np.abs(ends[n] - ends[2 * n]))) for n in (8, 16, 32, 64, 128, 256)}
    assert min(differences.values()) > 0.1 * 1e-12 * np.max(np.abs(X))  # no count agrees: the rounding
    assert differences[256] > 3 * min(differences.values())  # which grows with the steps
    assert chosen.steps == min(differences, key=differences.get) < 256


def test_every_mode_takes_the_same_count_of_steps_whatever_its_length(slip):
    """The event falls in the middle of the last of n steps: n + 1 nodes, the last at T."""
    outcome = HybridMap(slip).stride(np.array([0.95, 5.1]), theta(slip), Resolution(0.01, 8), nodes=True)
    for _, times, _ in outcome.nodes:
        assert len(times) == 9
        assert (times[-1] - times[-2]) / (times[1] - times[0]) == pytest.approx(0.5, abs=1e-6)


def test_a_mode_durations_and_nodes_are_reported(slip):
    outcome = HybridMap(slip).stride(np.array([0.95, 5.1]), theta(slip), FINE, nodes=True)
    assert [mode for mode, _, _ in outcome.nodes] == ["flight", "stance", "flight"]
    for (_, times, _), duration in zip(outcome.nodes, outcome.durations):
        assert times[-1] == pytest.approx(duration, abs=0)


def test_a_steep_landing_falls_with_the_falls_name(slip):
    """Landing with the leg 80 deg from the vertical at 5 m/s: the mass hits the ground."""
    outcome = HybridMap(slip).stride(np.array([0.3, 5.0]), theta(slip, attack_deg=10.0), FINE)
    assert not outcome.ok and outcome.failure == "fell: mass hit the ground (mode stance)"


def test_a_guard_that_never_fires_is_reported_with_its_event(slip):
    never = replace(SLIP, transitions=(replace(SLIP.transitions[0], guard=lambda s, p, u: s.ydot + 10.0),
                                       SLIP.transitions[1]))
    outcome = HybridMap(model_functions(never)).stride(np.array([0.95, 5.1]), theta(slip), Resolution(0.05, 8))
    assert outcome.failure.startswith("the guard of touchdown never fired")


def test_the_hoppers_damper_takes_energy_that_its_push_gives_back():
    f = model_functions(HOPPER)
    hybrid = HybridMap(f)
    values = {"m": 80.0, "k": 2e4, "c": 100.0, "l0": 1.0, "g": 9.81, "theta_td": 0.39}

    def energy_change(push):
        z, ydot = hybrid.stride(np.array([1.0, 5.0]), f.theta({**values, "push": push}), FINE).section
        return 0.5 * 80 * ydot**2 + 80 * 9.81 * z - (0.5 * 80 * 25 + 80 * 9.81)

    assert energy_change(0.0) < 0 < energy_change(0.04)


def test_an_apex_below_the_touchdown_height_is_refused_at_once(slip):
    """At z = 0.9 m the leg held 22 deg from the vertical already reaches below the ground."""
    outcome = HybridMap(slip).stride(np.array([0.9, apex_speed(0.9)]), theta(slip), FINE)
    assert outcome.failure == "mode flight starts past the guard of touchdown (it can never cross it)"


def test_an_event_that_falls_exactly_on_a_node_still_fires(slip):
    """A scout of a quarter of the descent's duration put touchdown on the fourth node
    (the guard exactly zero there); the mode then never ended. It fires at the node."""
    x = np.array([0.9379469070660286, 5.036397196638714])
    th = slip.theta({"m": 80.0, "k": 2e4, "l0": 1.0, "g": 9.81, "theta_td": math.radians(21.5)})
    hybrid = HybridMap(slip)
    descent = hybrid.stride(x, th, Resolution(0.02, 8)).durations[0]
    on_node = hybrid.stride(x, th, Resolution(descent / 4, 8))
    assert on_node.ok and on_node.durations[0] == pytest.approx(descent, rel=1e-12)


def test_the_map_is_the_same_compiled_or_in_the_virtual_machine(slip):
    """The chunks' values are the steps' own to the bit either way; the Jacobian's sums
    may round differently."""
    x, th = np.array([0.95, 5.1]), theta(slip)
    compiled = HybridMap(slip, compiled=True).stride(x, th, FINE, jacobian=True, nodes=True)
    interpreted = HybridMap(slip, compiled=False).stride(x, th, FINE, jacobian=True, nodes=True)
    assert np.array_equal(compiled.section, interpreted.section)
    assert compiled.durations == interpreted.durations
    for (_, t_compiled, x_compiled), (_, t_interpreted, x_interpreted) in zip(compiled.nodes, interpreted.nodes):
        assert np.array_equal(t_compiled, t_interpreted) and np.array_equal(x_compiled, x_interpreted)
    for a, b in zip(compiled.jacobians(), interpreted.jacobians()):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13)


def stepwise(hybrid: HybridMap) -> HybridMap:
    """``hybrid`` without its whole-stride calls: every mode takes its scout's and its run's
    calls, as a mode too long for the whole-stride call (and every mode after it) does."""
    stepping = HybridMap(hybrid.functions)
    stepping.__dict__["kernels"] = replace(hybrid.kernels, strides={})
    return stepping


@pytest.mark.parametrize("model", ["slip", "ba-slip"])
def test_a_stride_in_one_call_is_its_scouts_and_runs_to_the_bit(model, slip):
    """Strides, durations, nodes and Jacobians from perturbed starts: one call a stride,
    and the calls of each scout, run and event, give the same numbers; so does a scout too
    fine for the whole-stride call (over 64 of its steps), which takes the calls instead."""
    if model == "slip":
        functions, start, th = slip, np.array([0.95, 5.1]), theta(slip)
    else:  # the downward gait
        result = json.loads((Path(__file__).resolve().parents[1] / "results" / "downward" / "result.json").read_text())
        functions = model_functions(BA_SLIP, result["hip_law"])
        start = np.array([result["apex"][n] for n in APEX.names])
        th = functions.theta({**result["params"], **result["control"]})
    whole = HybridMap(functions)
    rng = np.random.default_rng(17)
    for resolution in (Resolution(0.01, 16), Resolution(0.001, 8)):
        for _ in range(5):
            x = start * (1 + 1e-3 * rng.standard_normal(len(start)))
            one = whole.stride(x, th, resolution, jacobian=True, nodes=True)
            calls = stepwise(whole).stride(x, th, resolution, jacobian=True, nodes=True)
            assert one.failure == calls.failure and one.durations == calls.durations
            if one.ok:
                assert np.array_equal(one.section, calls.section)
                assert all(np.array_equal(a, b) for a, b in zip(one.jacobians(), calls.jacobians()))
                for (_, t_one, x_one), (_, t_calls, x_calls) in zip(one.nodes, calls.nodes):
                    assert np.array_equal(t_one, t_calls) and np.array_equal(x_one, x_calls)


def test_a_stride_along_closed_form_flows_is_the_stride_by_dop853_alone():
    """The BA-SLIP's description steps its flight along the ballistic flow; without the
    flow its flight is integrated like any mode, and the strides agree."""
    result = json.loads((Path(__file__).resolve().parents[1] / "results" / "downward" / "result.json").read_text())
    functions = model_functions(BA_SLIP, result["hip_law"])
    X = np.array([result["apex"][n] for n in APEX.names])
    th = functions.theta({**result["params"], **result["control"]})
    resolution = Resolution(0.01, 32)
    along = HybridMap(functions).stride(X, th, resolution, jacobian=True)
    # In the virtual machine: the comparison is not worth a compile of its own.
    stepped = HybridMap(replace(functions, flows={}), compiled=False).stride(X, th, resolution, jacobian=True)
    assert np.max(np.abs(along.section - stepped.section)) <= 1e-12 * np.max(np.abs(X))
    for a, b in zip(along.jacobians(), stepped.jacobians()):
        assert np.max(np.abs(a - b)) <= 1e-10 * max(1.0, np.max(np.abs(b)))
