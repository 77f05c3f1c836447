"""Specification of baslip.problem.reader: YAML problem files and their validation; a bare
name that is no file here means the shipped problem of that name.

Every bad input raises ProblemError naming the offending key; the CLI turns it into one
line on stderr and exit code 2 (see test_solve.py).
"""

import math
import os
import pickle
import re

import pytest

from baslip.gait.from_problem import fixed_point_spec
from baslip.model.dynamics import Params
from baslip.model.quantities import DEFAULT_GUESS
from baslip.problem.reader import ProblemError, SolverSettings, load_problem, parse_problem

VALID = {
    "name": "ok",
    "params": {"m": 1.0, "I": 0.0033, "k": 1000.0, "rho0": 0.2, "d": 0.04, "g": 9.81},
    "fix": {"z": 0.4, "ydot": 0.5},
    "guess": {"theta_h": "-90 deg", "theta_td": 0.1},
}


def with_(**sections):
    data = {key: (dict(value) if isinstance(value, dict) else value) for key, value in VALID.items()}
    for key, value in sections.items():
        if isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key].update(value)
        else:
            data[key] = value
    return data


def test_valid_problem_is_parsed_into_si_and_radians():
    problem = parse_problem(with_(bounds={"theta_h": ["-100 deg", "-80 deg"]}, guess={"theta_h_dot": "30 deg/s"}))
    assert problem.fix == {"z": 0.4, "ydot": 0.5}
    assert problem.guess["theta_h"] == pytest.approx(-math.pi / 2)
    assert problem.guess["theta_h_dot"] == pytest.approx(math.pi / 6)
    assert problem.bounds["theta_h"] == pytest.approx((-100 * math.pi / 180, -80 * math.pi / 180))
    assert problem.full_guess()["Kp"] == DEFAULT_GUESS["Kp"]
    assert "z" not in problem.full_guess()


def test_shipped_problems_load():
    for name in ("downward", "upward"):
        problem = load_problem(f"problems/{name}.yaml")
        assert problem.name == name and problem.fix["ydot"] == 0.5 and problem.fix["z"] == 0.4


@pytest.mark.parametrize(
    "data, key, words",
    [
        (with_(speed=1.0), "speed", "unknown key"),
        (with_(fix={"zz": 0.4}), "fix.zz", "unknown key"),
        (with_(params={"mass": 1.0}), "params.mass", "unknown key"),
        (with_(solver={"iterations": 3}), "solver.iterations", "unknown key"),
        (with_(fix={"z": "high"}), "fix.z", "expected a number"),
        (with_(fix={"z": True}), "fix.z", "expected a number"),
        (with_(fix={"z": "0.4 deg"}), "fix.z", "expected a number"),
        (with_(guess={"theta_h": "90 furlongs"}), "guess.theta_h", "deg"),
        (with_(params=[1, 2]), "params", "expected a mapping"),
        (with_(fix={"z": float("nan")}), "fix.z", "finite"),
        (with_(guess={"Kp": float("inf")}), "guess.Kp", "finite"),
        (with_(params={"m": 0.0}), "params.m", "positive"),
        (with_(params={"I": -0.1}), "params.I", "positive"),
        (with_(params={"k": 0}), "params.k", "positive"),
        (with_(params={"rho0": -0.2}), "params.rho0", "positive"),
        (with_(params={"g": 0.0}), "params.g", "positive"),
        (with_(params={"d": -0.01}), "params.d", "zero or positive"),
        (with_(fix={"z": 0.15}), "fix.z", "foot below ground"),
        (with_(fix={"z": 0.9}, bounds={"z": [0.3, 0.7]}), "fix.z", "outside bounds"),
        (with_(bounds={"z": [0.7, 0.3]}), "bounds.z", "exceeds"),
        (with_(bounds={"z": [0.3]}), "bounds.z", "[lo, hi]"),
        (with_(guess={"z": 0.5}), "guess.z", "fixed"),
        (with_(guess={"theta_td": 2.0}), "guess.theta_td", "physical range"),
        (with_(objective="fastest"), "objective", "expected one of"),
        (with_(solver={"nodes": 1}), "solver.nodes", "integer"),
        (with_(solver={"tol": -1.0}), "solver.tol", "expected a tolerance"),
        (with_(name="a b/c"), "name", "name"),
        (with_(name=".."), "name", "name"),
        (with_(objective=["min_torque"]), "objective", "expected one of"),
        (with_(fix={"z": 10**400}), "fix.z", "too large"),
        (with_(fix={"z\nq": 0.4}), "fix.z q", "unknown key"),
        (with_(bounds={"z": [12, 20]}), "bounds.z", "physical range"),
        (with_(bounds={"theta_td": [1.52, 1.56]}), "bounds.theta_td", "physical range"),
        (with_(fix={"energy": 1.0}), "fix.energy", "below the least apex energy"),
        (with_(fix={"energy": 5.0, "theta_h_dot": 0.0}), "fix.energy", "contradicts"),
        (with_(strides=0), "strides", "integer in [1, 16]"),
        (with_(strides=2.0), "strides", "integer in [1, 16]"),
        (with_(strides=True), "strides", "integer in [1, 16]"),
        (with_(strides=2, study={"kind": "sweep", "vary": {"ydot": [0.4, 0.6, 0.1]}}), "strides", "one-stride"),
        (with_(continuation={"parameter": "z", "range": [0.3, 0.5], "switch": "fold"}),
         "continuation.switch", "period_doubling"),
    ],
)
def test_bad_input_names_the_key(data, key, words):
    with pytest.raises(ProblemError) as err:
        parse_problem(data)
    assert err.value.key.replace("\n", "\\n") == key
    assert words in str(err.value)
    assert "\n" not in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(ProblemError, match="no such problem file"):
        load_problem(tmp_path / "absent.yaml")


def test_a_bare_name_means_the_shipped_problem_unless_a_file_here_has_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_problem("downward").name == load_problem("downward.yaml").name == "downward"
    assert load_problem("downward").fix["z"] == 0.4
    (tmp_path / "downward.yaml").write_text("name: mine\nfix: {z: 0.41, ydot: 0.5}\n")
    assert load_problem("downward.yaml").name == "mine"  # the user's copy comes first
    with pytest.raises(ProblemError, match="nor the name of a shipped problem"):
        load_problem("no_such_problem")
    with pytest.raises(ProblemError, match="no such problem file") as err:
        load_problem(tmp_path / "sub" / "downward.yaml")  # a path with folders means that path
    assert "shipped" not in str(err.value)


def test_malformed_yaml_reports_the_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: bad\nfix: {z: 0.4\n")
    with pytest.raises(ProblemError, match=r"malformed YAML at line \d+"):
        load_problem(path)


def test_top_level_must_be_a_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ProblemError, match="expected a mapping"):
        load_problem(path)


def test_numbers_yaml_leaves_as_strings_are_read(tmp_path):
    """YAML 1.1 reads 1e-8 (no dot) as a string; it is still a number here."""
    path = tmp_path / "p.yaml"
    path.write_text("solver: {tol: 1e-8}\nfix: {z: 4e-1, ydot: 0.5}\n")
    problem = load_problem(path)
    assert problem.solver.tol == 1e-8 and problem.fix["z"] == 0.4


def test_defaults_are_clipped_into_the_bounds():
    """theta_h defaults to +90 deg; with bounds around -90 deg it starts inside them."""
    problem = parse_problem({"fix": {"z": 0.23, "ydot": 0.5}, "bounds": {"theta_h": ["-100 deg", "-80 deg"]}})
    assert problem.start_value("theta_h") == pytest.approx(math.radians(-80))


@pytest.mark.parametrize(
    "content, words",
    [
        (b"", "empty"),
        (b"\xff\xfe fix", "not UTF-8"),
        (b"[" * 5000, "malformed YAML"),
        (b"fix: {z: 0.4}\nfix: {z: 0.5}\n", "duplicate key"),
    ],
)
def test_unreadable_files_are_one_line_errors(tmp_path, content, words):
    path = tmp_path / "p.yaml"
    path.write_bytes(content)
    with pytest.raises(ProblemError) as err:
        load_problem(path)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_default_name_comes_from_a_sanitised_file_name(tmp_path):
    path = tmp_path / "sp ace.yaml"
    path.write_text("fix: {z: 0.4}\n")
    assert load_problem(path).name == "sp_ace"


def test_strides_and_switch_are_read():
    problem = parse_problem(with_(
        strides=2, continuation={"parameter": "z", "range": [0.3, 0.5], "switch": "period_doubling"},
    ))
    assert problem.strides == 2 and problem.continuation.switch == "period_doubling"
    assert parse_problem(VALID).strides == 1 and load_problem("problems/downward_period2.yaml").strides == 2


# --- a problem changed in Python is checked like a file ------------------------------------


def test_replace_refuses_what_a_file_would_refuse_with_the_same_message():
    problem = parse_problem(VALID)
    with pytest.raises(ProblemError) as from_file:
        parse_problem(with_(fix={"z": -1.0}))
    with pytest.raises(ProblemError) as from_python:
        problem.replace(fix={"z": -1.0, "ydot": 0.5})
    assert str(from_python.value) == str(from_file.value) and from_python.value.key == "fix.z"


def test_replace_checks_the_sections_together_and_refuses_unknown_keys():
    problem = parse_problem(VALID)
    with pytest.raises(ProblemError, match="either a study or a continuation"):
        problem.replace(study={"kind": "sweep", "vary": {"ydot": [0.4, 0.5, 0.1]}},
                        continuation={"parameter": "ydot", "range": [0.4, 0.6]})
    with pytest.raises(ProblemError) as caught:
        problem.replace(fixed={"z": 0.4})
    assert caught.value.key == "fixed" and "unknown key" in str(caught.value)


def test_replace_keeps_what_it_is_not_given_and_takes_parsed_objects():
    problem = parse_problem(VALID)
    stiffer = problem.replace(params=Params(k=2000.0), guess={"theta_td": "6 deg"})
    assert stiffer.params.k == 2000.0 and stiffer.fix == problem.fix
    assert stiffer.guess == {"theta_td": pytest.approx(math.radians(6))}
    with pytest.raises(ProblemError, match="params.k"):
        problem.replace(params=Params(k=-1.0))


def test_parse_problem_takes_params_and_solver_objects():
    problem = parse_problem({**VALID, "params": Params(m=2.0), "solver": SolverSettings(nodes=30)})
    assert problem.params.m == 2.0 and problem.solver.nodes == 30


def test_a_problem_travels_to_workers_as_data():
    problem = parse_problem(with_(study={"kind": "sweep", "vary": {"ydot": [0.4, 0.5, 0.1]}}))
    copy = pickle.loads(pickle.dumps(problem))
    assert copy == problem and type(copy.fix) is type(problem.fix)
    with pytest.raises(TypeError):
        copy.fix["z"] = 1.0  # still read-only after the trip


def test_a_continuation_that_defines_no_branch_is_refused_when_read():
    branch = {"parameter": "ydot", "range": [0.4, 0.6]}
    unfixed = {**with_(continuation=branch), "fix": {"z": 0.4}}
    with pytest.raises(ProblemError) as caught:
        parse_problem(unfixed)
    assert caught.value.key == "continuation.parameter" and "must be fixed" in str(caught.value)
    with pytest.raises(ProblemError, match="as many free quantities as equations") as caught:
        parse_problem(with_(continuation=branch, objective="min_torque"))
    assert caught.value.key == "fix"
    parse_problem(with_(continuation=branch))  # nearest_guess picks the family


def test_a_sweep_step_below_the_rounding_of_its_values_is_refused():
    tiny = {"kind": "sweep", "vary": {"z": [0.4, 0.40000000001, 1e-13]}}
    with pytest.raises(ProblemError) as caught:
        parse_problem(with_(study=tiny, fix={"ydot": 0.5}))
    assert caught.value.key == "study.vary.z" and "finer than the 1e-12" in str(caught.value)
    fine = {"kind": "sweep", "vary": {"z": [0.4, 0.40000000001, 1e-12]}}
    assert len(parse_problem(with_(study=fine)).study.axes[0].values) == 11


def test_each_re_solving_controller_runs_its_own_number_of_starts():
    """``solve_samples``: one count for both re-solves, or one each (a missing one runs
    ``samples``), never more than ``samples``; the batched controllers run ``samples``."""
    study = {"kind": "controllers", "perturbation": {"z": 0.001}, "samples": 400}

    def starts(solve_samples):
        parsed = parse_problem(with_(study={**study, "solve_samples": solve_samples})).study
        return [parsed.starts(name) for name in ("constant", "feedback", "horizon", "resolve")]

    assert starts(None) == [400, 400, 400, 400]
    assert starts(50) == [400, 400, 50, 50]
    assert starts({"horizon": 300}) == [400, 400, 300, 400]
    assert starts({"horizon": 300, "resolve": 20}) == [400, 400, 300, 20]
    assert starts({"horizon": 1000}) == [400, 400, 400, 400]


# --- defaults that follow the body --------------------------------------------------------

HUMAN = {"m": 80.0, "I": 4.58, "k": 20000.0, "rho0": 1.0, "d": 0.1, "g": 9.81}


def _scaled_body(length: float, mass: float) -> dict[str, float]:
    """The thesis's body with lengths times ``length`` and masses times ``mass`` (g kept,
    so times scale by sqrt(length))."""
    thesis = Params()
    return {"m": thesis.m * mass, "I": thesis.I * mass * length**2, "k": thesis.k * mass / length,
            "rho0": thesis.rho0 * length, "d": thesis.d * length, "g": thesis.g}


@pytest.mark.parametrize("law", ["pd", "vpp"])
def test_defaults_of_a_scaled_body_are_the_thesis_defaults_scaled_by_their_dimension(law):
    length, mass = 4.0, 2.0
    problem = parse_problem({"params": _scaled_body(length, mass), "hip_law": law})
    time = math.sqrt(length)
    factors = {"z": length, "theta_h": 1.0, "ydot": length / time, "theta_h_dot": 1 / time, "Kp": mass * length**2 / time**2,
               "Kd": mass * length**2 / time, "theta2_des": 1.0, "theta2_dot_des": 1 / time, "theta_td": 1.0,
               "r_vpp": length}
    thesis = parse_problem({"hip_law": law})
    for name in problem.design:
        assert problem.start_value(name) == pytest.approx(thesis.start_value(name) * factors[name], rel=1e-14), name
    spec = fixed_point_spec(problem)
    for name in problem.design:
        lo, hi = fixed_point_spec(thesis).bounds_of(name)
        assert spec.bounds_of(name) == pytest.approx((lo * factors[name], hi * factors[name]), rel=1e-14), name


def test_the_thesis_body_keeps_its_defaults_exactly():
    problem = parse_problem({"hip_law": "pd"})
    assert problem.full_guess() == {name: DEFAULT_GUESS[name] for name in problem.design}


def test_a_human_sweep_over_z_without_a_z_guess_is_accepted():
    """Issue 56: the thesis's default z = 0.4 m refused a human body's sweep over z."""
    problem = parse_problem({"params": HUMAN, "hip_law": "vpp", "fix": {"ydot": 3.0, "r_vpp": 0.1},
                             "guess": {"theta_h": "90 deg", "theta_td": "17 deg"},
                             "study": {"kind": "sweep", "vary": {"z": [1.1, 1.2, 0.05]}}})
    assert problem.start_value("z") == pytest.approx(0.4 * 5)
    assert problem.start_value("ydot") == 3.0


def test_a_human_gain_beyond_the_thesis_bound_is_accepted():
    problem = parse_problem({"params": HUMAN, "fix": {"z": 1.1, "ydot": 3.0}, "guess": {"Kp": 2000.0}})
    assert problem.guess["Kp"] == 2000.0


def test_a_default_that_cannot_serve_names_itself_a_default_and_what_to_write():
    with pytest.raises(ProblemError) as caught:
        parse_problem({"params": HUMAN, "hip_law": "vpp", "guess": {"theta_h": "90 deg", "theta_td": "17 deg"},
                       "bounds": {"z": [0.5, 0.9]}})
    assert caught.value.key == "guess.z"
    assert "default for this body" in caught.value.message and "write guess.z above 1.056 m" in caught.value.message
    assert "theta_td = 17 deg" in caught.value.message and "rad" not in caught.value.message


def test_a_written_value_is_not_called_a_default():
    with pytest.raises(ProblemError) as caught:
        parse_problem({"params": HUMAN, "hip_law": "vpp", "guess": {"z": 0.8, "theta_h": "90 deg"}})
    assert caught.value.key == "guess.z" and "default" not in caught.value.message


def test_messages_give_angles_in_degrees_as_they_were_written():
    """Issue 56: an input of "17 deg" came back as ``theta_td = 0.2967 rad``."""
    with pytest.raises(ProblemError) as caught:
        parse_problem(with_(guess={"theta_td": "17 deg"}, bounds={"theta_td": ["0 deg", "10 deg"]}))
    assert caught.value.key == "guess.theta_td"
    assert caught.value.message == "17 deg lies outside bounds.theta_td = [0 deg, 10 deg]"


@pytest.mark.parametrize(("continuation", "key", "names"), [
    ({"parameter": "speed", "range": [0.4, 0.6]}, "continuation.parameter", ("ydot", "energy", "rho0")),
    ({"parameter": "r_vpp", "range": [0.0, 0.1]}, "continuation.parameter", ("ydot", "energy", "rho0")),
    ({"parameter": "ydot", "range": [0.4, 0.6], "plot": "height"}, "continuation.plot", ("z", "theta_td")),
    ({"parameter": "ydot", "range": [0.4, 0.6], "plot": "r_vpp"}, "continuation.plot", ("z", "Kp", "theta_td")),
])
def test_a_refused_continuation_name_lists_the_accepted_ones(continuation, key, names):
    """Issue 56: a refused continuation.plot or parameter did not say what it accepts."""
    with pytest.raises(ProblemError) as caught:
        parse_problem(with_(continuation=continuation, guess={"Kp": 0.0}))
    assert caught.value.key == key
    assert all(re.search(rf"\b{name}\b", caught.value.message) for name in names), caught.value.message


def test_an_infinite_end_of_a_bound_written_in_a_file_is_no_bound(tmp_path):
    """-.inf below and .inf above mean what null means; the other way round they are refused."""
    path = tmp_path / "open.yaml"
    path.write_text("fix: {z: 0.4, ydot: 0.5}\nbounds: {z: [-.inf, 0.6], ydot: [0.1, .inf]}\n")
    assert dict(load_problem(path).bounds) == {"z": (-math.inf, 0.6), "ydot": (0.1, math.inf)}
    path.write_text("fix: {z: 0.4, ydot: 0.5}\nbounds: {z: [.inf, 0.6]}\n")
    with pytest.raises(ProblemError, match="^bounds.z: expected a finite number"):
        load_problem(path)


@pytest.mark.parametrize("tagged", ["!!float 'abc'", "!!int '0x'", "!!float ''", "!!int 'twelve'"])
def test_a_number_tag_on_text_that_is_no_number_names_its_key(tmp_path, tagged):
    """Issue 57: these raised ValueError from inside PyYAML's constructors."""
    path = tmp_path / "tagged.yaml"
    path.write_text(f"fix: {{z: 0.4, ydot: 0.5}}\nguess: {{Kp: {tagged}}}\n")
    with pytest.raises(ProblemError) as err:
        load_problem(path)
    assert err.value.key == "guess.Kp" and tagged in str(err.value) and "\n" not in str(err.value)


def test_well_formed_number_tags_still_read(tmp_path):
    path = tmp_path / "tagged.yaml"
    path.write_text("fix: {z: !!float '0.4', ydot: 0.5}\nsolver: {max_iter: !!int '0x10'}\n")
    problem = load_problem(path)
    assert problem.fix["z"] == 0.4 and problem.solver.max_iter == 16


def test_a_fifo_as_the_problem_is_refused_without_waiting(tmp_path):
    """Issue 57: reading a FIFO with no writer hung; it is refused before any read."""
    fifo = tmp_path / "problem.yaml"
    os.mkfifo(fifo)
    with pytest.raises(ProblemError, match="is a FIFO, not a file"):
        load_problem(fifo)


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom", "/dev/null"])
def test_a_device_as_the_problem_is_refused(device):
    """Issue 57: /dev/zero and /dev/urandom were read until memory ran out."""
    if not os.path.exists(device):
        pytest.skip(f"no {device} here")
    with pytest.raises(ProblemError, match="is a character device, not a file"):
        load_problem(device)
