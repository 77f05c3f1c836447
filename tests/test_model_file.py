"""Problem files of described models: the model named by file or by name, every key
checked, and a bad entry or a bad description refused with its key."""

import math
import textwrap
from pathlib import Path

import pytest

from baslip.errors import ProblemError, ProblemKindError
from baslip.problem.model_file import ModelProblem, load_any_problem, parse_model_problem
from baslip.problem.reader import Problem, load_problem

ROOT = Path(__file__).resolve().parents[1]
HOPPER = {"model": "models/hopper.py:HOPPER", "fix": {"z": 1.0, "ydot": 5.0}, "guess": {"theta_td": "22 deg",
                                                                                        "push": 0.01}}


def parse(data, folder=ROOT / "problems"):
    return parse_model_problem(data, "test", folder)


def test_the_shipped_hopper_problem_names_its_model_file_beside_it():
    problem = load_any_problem(ROOT / "problems" / "hopper.yaml")
    assert isinstance(problem, ModelProblem) and problem.spec.model.name == "hopper"
    assert problem.spec.guess["theta_td"] == pytest.approx(math.radians(22.0))
    assert problem.continuation.parameter == "ydot" and (problem.continuation.low, problem.continuation.high) == (3, 7)


def test_a_built_in_model_is_named_by_its_name():
    problem = load_any_problem(ROOT / "problems" / "slip_attack.yaml")
    assert problem.spec.model.name == "slip" and problem.spec.fixed_invariants == {"energy": 1784.8}


def test_model_ba_slip_is_the_ba_slips_own_problem(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text("model: ba-slip\n" + (ROOT / "problems" / "downward.yaml").read_text())
    assert isinstance(load_any_problem(path), Problem)
    assert load_problem(path).name == "downward"


def test_the_ba_slip_reader_sends_a_described_model_elsewhere():
    with pytest.raises(ProblemKindError, match=r"model: 'models/hopper.py:HOPPER' is a described model's problem"):
        load_problem(ROOT / "problems" / "hopper.yaml")


@pytest.mark.parametrize("change, key, words", [
    ({"model": "nowhere.py:X"}, "model", "no such model file"),
    ({"model": "models/hopper.py:HOP"}, "model", "HOP in hopper.py is nothing, not a baslip Model"),
    ({"model": "models/hopper.py:ca"}, "model", "is module, not a baslip Model"),
    ({"model": "crawler"}, "model", "neither a built-in model"),
    ({"model": 3}, "model", "expected a model's name"),
    ({"law": "pd"}, "law", "'pd' is not a law of hopper"),
    ({"fix": {"z": 1.0, "ydot": 5.0, "Kp": 1.0}}, "fix.Kp", "unknown key"),
    ({"guess": {"theta_td": "22 furlongs", "push": 0.01}}, "guess.theta_td", "expected a number"),
    ({"fix": {"z": 1.0}}, "guess.ydot", "is a section coordinate: fix it or guess it"),
    ({"params": {"z": 1.0}}, "params.z", "unknown key"),
    ({"bounds": {"push": [0.2, 0.1]}}, "bounds.push", "low end"),
    ({"bounds": {"push": 0.1}}, "bounds.push", "expected [low, high]"),
    ({"solver": {"nodes": 1}}, "solver.nodes", "at least 2"),
    ({"solver": {"tolerance": 1.0}}, "solver.tolerance", "must lie in"),
    ({"study": {"kind": "grid"}}, "study.kind", "runs a gait, a continuation or a study of kind atlas, controllers"),
    ({"study": {"kind": "sweep", "sweep": {"push": [0.1]}}}, "study.sweep.push", "expected a fixed quantity"),
    ({"study": {"kind": "sweep", "sweep": {"ydot": {"from": 3, "to": 7, "count": 1}}}}, "study.sweep.ydot.count",
     "at least 2"),
    ({"fix": {"z": 1.0, "ydot": 5.0, "theta_td": 0.4}, "guess": {"push": 0.01},
      "study": {"kind": "sweep", "sweep": {"theta_td": [0.4, 3.0]}}}, "study.sweep.theta_td", "outside theta_td's range"),
    ({"study": {"kind": "sweep", "sweep": {"ydot": [3], "z": [1], "k": [1]}}}, "study.sweep", "one or two"),
    ({"study": {"kind": "sweep", "sweep": {"ydot": {"from": 1, "to": 9, "count": 101},
                                           "z": {"from": 1, "to": 2, "count": 101}}}}, "study.sweep", "at most"),
    ({"study": {"kind": "controllers", "grid": 1}}, "study.grid", "expected an integer in [2, 101]"),
    ({"study": {"kind": "controllers", "spread": 1.5}}, "study.spread", "must lie in (0, 1)"),
    ({"study": {"kind": "controllers", "max_charts": 9}}, "study.max_charts", "unknown key"),
    ({"study": {"kind": "atlas", "max_charts": 0}}, "study.max_charts", "expected an integer"),
    ({"study": {"kind": "atlas", "plot": ["theta_td", "z"]}}, "study.plot", "expected two different free quantities"),
    ({"continuation": {"parameter": "push", "range": [0, 1]}}, "continuation.parameter", "expected a fixed quantity"),
    ({"continuation": {"parameter": "ydot", "range": [6, 7]}}, "continuation.range", "strictly inside"),
    ({"speed": 3}, "speed", "unknown key"),
    ({"continuation": {"parameter": "ydot", "range": [3, 7], "second": "z"}}, "continuation.second_range",
     "come together"),
    ({"continuation": {"parameter": "ydot", "range": [3, 7], "second": "ydot", "second_range": [0, 9],
                       "follow": ["fold"]}}, "continuation.second", "other than ydot"),
    ({"continuation": {"parameter": "ydot", "range": [3, 7], "second": "z", "second_range": [0.5, 1.5],
                       "follow": ["cusp"]}}, "continuation.follow", "distinct curve kinds"),
    ({"continuation": {"parameter": "ydot", "range": [3, 7], "second": "z", "second_range": [1.5, 2.0],
                       "follow": ["fold"]}}, "continuation.second_range", "strictly inside"),
])
def test_a_bad_entry_is_refused_naming_its_key(change, key, words):
    with pytest.raises(ProblemError) as refused:
        parse({**HOPPER, **change})
    assert refused.value.key == key and words in refused.value.message


def test_a_control_left_unguessed_is_fixed_at_its_default():
    problem = parse({**HOPPER, "guess": {"theta_td": 0.4}})
    assert problem.spec.free == ("theta_td",) and problem.spec.values()["push"] == 0.01


def test_a_description_that_cannot_run_is_refused_naming_its_part(tmp_path):
    (tmp_path / "broken.py").write_text(textwrap.dedent("""
        from dataclasses import replace
        from baslip.model.catalogue.slip import SLIP
        BROKEN = replace(SLIP, section=replace(SLIP.section, coordinates=("z", "vy")))
    """))
    with pytest.raises(ProblemError) as refused:
        parse({"model": "broken.py:BROKEN", "fix": {"z": 1.0}, "guess": {"vy": 5.0}}, tmp_path)
    assert refused.value.key == "model.section.coordinates" and "'vy' is not a state" in refused.value.message


def test_a_model_file_that_raises_is_named_with_its_error(tmp_path):
    (tmp_path / "raises.py").write_text("raise RuntimeError('no such physics')\n")
    with pytest.raises(ProblemError, match=r"model: importing raises.py raised RuntimeError: no such physics"):
        parse({"model": "raises.py:X"}, tmp_path)


def test_the_shipped_band_follows_both_edges_in_the_energy():
    problem = load_any_problem(ROOT / "problems" / "slip_band.yaml")
    assert problem.continuation.second == "energy" and problem.continuation.follow == ("period_doubling", "fold")
    assert problem.continuation.second_range == (1424.8, 2224.8)


def test_with_no_guess_every_coordinate_and_control_not_fixed_is_free_from_the_reference():
    problem = parse({"model": "models/hopper.py:HOPPER", "params": {"m": 2.5, "l0": 0.17}, "fix": {"z": 0.17}})
    assert problem.from_reference and problem.spec.free == ("ydot", "theta_td", "push")
    assert problem.to_dict()["start"].startswith("the model's reference gait")


def test_with_no_guess_a_model_without_a_reference_asks_for_one(tmp_path):
    (tmp_path / "bare.py").write_text("from dataclasses import replace\nfrom baslip.model.catalogue.slip import SLIP\n"
                                      "BARE = replace(SLIP, reference={})\n")
    with pytest.raises(ProblemError, match=r"guess: model slip names no reference gait"):
        parse({"model": "bare.py:BARE", "fix": {"z": 1.0, "theta_td": 0.4}}, tmp_path)


def test_a_sweep_reads_lists_and_spacings_in_each_quantitys_unit():
    problem = parse({**HOPPER, "fix": {"z": 1.0, "ydot": 5.0, "theta_td": 0.4}, "guess": {"push": 0.01},
                     "study": {"kind": "sweep", "sweep": {"ydot": {"from": 3, "to": 7, "count": 5},
                                                          "theta_td": ["20 deg", "25 deg"]}}})
    axes = dict(problem.sweep.axes)
    assert axes["ydot"] == (3.0, 4.0, 5.0, 6.0, 7.0) and axes["theta_td"] == pytest.approx((0.349066, 0.436332), abs=1e-6)
    assert problem.sweep.points == 10
