"""Specification of rejected Python calls: the return map, the model parameters, a gait's
motion, results folders, problem mappings and ``baslip.run`` (issue 57, class 2).

Every bad argument raises an :class:`~baslip.errors.InputError` subclass whose one-line
message names the argument, before any compiled code runs, and nothing is written. Counts
and sizes that would exhaust memory or run without end are refused with the limit in the
message; the calls that crashed the interpreter (signal 11) now raise in a child process
that lives on; a stride whose hip is far too stiff ends as a named fall at its work limit.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from baslip.engine import arguments, driver
from baslip.engine.returnmap import Fall, ReturnMap, Tolerances
from baslip.engine.trajectory import Motion, TrunkRange, motion, stride_trajectory
from baslip.errors import ArgumentError, InputError, ProblemError
from baslip.gait.fixedpoint import FixedPointResult
from baslip.gait.ipopt_report import SolverReport
from baslip.model.dynamics import Params
from baslip.problem.reader import load_problem, parse_problem
from baslip.results import DamagedResults, open_results
from baslip.status import Status

ROOT = Path(__file__).resolve().parents[1]
X = [0.4, math.pi / 2, 0.5, 0.0]  # z [m], theta_h [rad], ydot [m/s], theta_h_dot [rad/s]
U = [1.0, 0.1, 3.0, 0.0, 0.3]  # Kp, Kd, theta2_des, theta2_dot_des, theta_td
P = Params()
MAP = ReturnMap()
#: Many rows without the memory: a read-only view of one row.
MANY = np.broadcast_to(np.array(X), (arguments.MAX_APEXES + 1, 4))


def downward() -> dict:
    return yaml.safe_load((ROOT / "problems" / "downward.yaml").read_text())


def nested(depth: int) -> list:
    top = inner = []
    for _ in range(depth):
        inner.append([])
        inner = inner[0]
    return top


def itself() -> list:
    loop: list = []
    loop.append(loop)
    return loop


def gait() -> FixedPointResult:
    """A gait record (not solved: its trajectory is all these calls need)."""
    return FixedPointResult("g", Status.FAILED, "", SolverReport("", 0, 0.0), P, np.array(X), np.array(U),
                            None, 0.0, None, None)


def results_folder(tmp: Path, content: bytes | None) -> Path:
    """A folder whose result.json holds ``content`` (a folder in its place for None)."""
    folder = tmp / "run"
    folder.mkdir()
    if content is None:
        (folder / "result.json").mkdir()
    else:
        (folder / "result.json").write_bytes(content)
    return folder


def run(**options):
    from baslip import run as run_problem

    return run_problem("downward", progress=False, **options)


#: (id, call, error class, what the message must name). A call takes the test's scratch folder.
CASES = [
    # -- the map's settings
    ("plugin bogus", lambda t: ReturnMap(plugin="bogus"), ArgumentError, "plugin: expected one of compiled, erk"),
    ("plugin number", lambda t: ReturnMap(plugin=3), ArgumentError, "plugin"),
    ("compiled too tight", lambda t: ReturnMap(Tolerances(1e-13, 1e-13), plugin="compiled"), ArgumentError, "plugin"),
    ("tolerances text", lambda t: ReturnMap("tight"), ArgumentError, "tolerances"),
    ("rtol zero", lambda t: ReturnMap(Tolerances(0.0, 1e-10)), ArgumentError, "tolerances.rtol"),
    ("atol nan", lambda t: ReturnMap(Tolerances(1e-10, math.nan)), ArgumentError, "tolerances.atol"),
    ("compile number", lambda t: ReturnMap(compile=3), ArgumentError, "compile"),
    ("law text", lambda t: ReturnMap(law="pd"), ArgumentError, "law"),
    ("hip_law bogus", lambda t: ReturnMap(hip_law="bogus"), InputError, "hip_law"),
    # -- one stride: shapes and types of X, u and params
    ("stride X of 3", lambda t: MAP.stride(X[:3], U, P), ArgumentError, "X: expected 4 numbers"),
    ("stride X of 5", lambda t: MAP.stride(X + [0.0], U, P), ArgumentError, "X: expected 4 numbers"),
    ("stride X text", lambda t: MAP.stride("fast", U, P), ArgumentError, "X: expected numbers"),
    ("stride X None", lambda t: MAP.stride(None, U, P), ArgumentError, "X"),
    ("stride X ragged", lambda t: MAP.stride([0.4, [1, 2], 0.5, 0], U, P), ArgumentError, "X"),
    ("stride X 2x2", lambda t: MAP.stride(np.ones((2, 2)), U, P), ArgumentError, "X"),
    ("stride u of 4", lambda t: MAP.stride(X, U[:4], P), ArgumentError, "u: expected 5 numbers"),
    ("stride u of 6", lambda t: MAP.stride(X, U + [0.0], P), ArgumentError, "u: expected 5 numbers"),
    ("stride u text", lambda t: MAP.stride(X, "slow", P), ArgumentError, "u"),
    ("stride params of 5", lambda t: MAP.stride(X, U, [1, 1, 1, 1, 1]), ArgumentError, "params: expected 6"),
    ("stride params text", lambda t: MAP.stride(X, U, "heavy"), ArgumentError, "params"),
    ("stride params m = 0", lambda t: MAP.stride(X, U, [0, 0.0033, 1000, 0.2, 0.04, 9.81]), ArgumentError,
     "params.m: must be positive"),
    ("stride params k < 0", lambda t: MAP.stride(X, U, [1, 0.0033, -1, 0.2, 0.04, 9.81]), ArgumentError, "params.k"),
    ("stride params g huge", lambda t: MAP.stride(X, U, [1, 0.0033, 1000, 0.2, 0.04, 1e9]), ArgumentError, "params.g"),
    ("call X of 3", lambda t: MAP(X[:3], U, P), ArgumentError, "X"),
    ("linearised X of 5", lambda t: MAP.linearised_stride(X + [1.0], U, P), ArgumentError, "X"),
    ("touchdown_guess p of 5", lambda t: ReturnMap.touchdown_guess(X, U, [1, 1, 1, 1, 1]), ArgumentError, "p"),
    # -- Jacobians of r^n
    ("jacobians strides 0", lambda t: MAP.jacobians(X, U, P, strides=0), ArgumentError, "strides"),
    ("jacobians strides 1.5", lambda t: MAP.jacobians(X, U, P, strides=1.5), ArgumentError, "strides"),
    ("jacobians strides text", lambda t: MAP.jacobians(X, U, P, strides="2"), ArgumentError, "strides"),
    ("jacobians strides True", lambda t: MAP.jacobians(X, U, P, strides=True), ArgumentError, "strides"),
    ("jacobians strides 1e9", lambda t: MAP.jacobians(X, U, P, strides=10**9), ArgumentError, "strides"),
    ("all_jacobians strides -1", lambda t: MAP.all_jacobians(X, U, P, strides=-1), ArgumentError, "strides"),
    ("parameter_jacobian u of 4", lambda t: MAP.parameter_jacobian(X, U[:4], P), ArgumentError, "u"),
    # -- second derivatives
    ("hessian W of 3", lambda t: MAP.hessian_vectors(X, U, P, np.ones(3), np.ones((15, 2))), ArgumentError, "W"),
    ("hessian S of 14 rows", lambda t: MAP.hessian_vectors(X, U, P, np.ones(4), np.ones((14, 2))), ArgumentError,
     "S: expected shape (15, K)"),
    ("hessian W columns", lambda t: MAP.hessian_vectors(X, U, P, np.ones((4, 3)), np.ones((15, 2))), ArgumentError,
     "W"),
    ("hessian S 3-d", lambda t: MAP.hessian_vectors(X, U, P, np.ones(4), np.ones((15, 2, 2))), ArgumentError, "S"),
    ("hessian S text", lambda t: MAP.hessian_vectors(X, U, P, np.ones(4), "all"), ArgumentError, "S"),
    ("hessian X of 3", lambda t: MAP.hessian_vectors(X[:3], U, P, np.ones(4), np.ones((15, 0))), ArgumentError, "X"),
    ("gradient G 3x3", lambda t: MAP.jacobian_gradient(X, U, P, np.ones((3, 3))), ArgumentError, "G"),
    ("gradient G nan", lambda t: MAP.jacobian_gradient(X, U, P, np.full((4, 4), math.nan)), ArgumentError, "G"),
    ("gradient G text", lambda t: MAP.jacobian_gradient(X, U, P, "seed"), ArgumentError, "G"),
    # -- many strides
    ("strides rows of 3", lambda t: MAP.strides(np.ones((2, 3)), U, P), ArgumentError, "X: expected rows of 4"),
    ("strides U rows", lambda t: MAP.strides(np.ones((3, 4)), np.ones((2, 5)), P), ArgumentError, "U"),
    ("strides too many rows", lambda t: MAP.strides(MANY, U, P), ArgumentError, "X: 2000001 rows exceed the limit"),
    ("simulate strides 1.5", lambda t: MAP.simulate(X, U, P, 1.5), ArgumentError, "strides: expected a whole number"),
    ("simulate strides 1e9", lambda t: MAP.simulate(X, U, P, 10**9), ArgumentError, "strides: must be from 1 to 100000"),
    ("simulate strides 0", lambda t: MAP.simulate(X, U, P, 0), ArgumentError, "strides"),
    ("simulate strides None", lambda t: MAP.simulate(X, U, P, None), ArgumentError, "strides"),
    ("simulate strides 5000 digits", lambda t: MAP.simulate(X, U, P, 10**5000), ArgumentError,
     "strides: must be from 1 to 100000, got an integer of about 5001 digits"),
    ("simulate X0 of 3", lambda t: MAP.simulate(X[:3], U, P, 2), ArgumentError, "X0"),
    ("simulate_many 2e6 apexes", lambda t: MAP.simulate_many(MANY[:2_000_000], U, P, 1), ArgumentError,
     "X0: 2000000 rows x 2 apexes exceed the limit of 2000000"),
    ("simulate_many strides 1.5", lambda t: MAP.simulate_many([X, X], U, P, 1.5), ArgumentError, "strides"),
    ("simulate_many U rows", lambda t: MAP.simulate_many([X, X], np.ones((3, 5)), P, 1), ArgumentError, "U"),
    # -- stance samples (n = 0 crashed the interpreter)
    ("stance n 0", lambda t: MAP.stance_samples(np.ones(6), U, P, 0.1, 0), ArgumentError, "n: must be from 1"),
    ("stance n -1", lambda t: MAP.stance_samples(np.ones(6), U, P, 0.1, -1), ArgumentError, "n"),
    ("stance n 1.5", lambda t: MAP.stance_samples(np.ones(6), U, P, 0.1, 1.5), ArgumentError, "n"),
    ("stance n 1e9", lambda t: MAP.stance_samples(np.ones(6), U, P, 0.1, 10**9), ArgumentError, "n"),
    ("stance duration 0", lambda t: MAP.stance_samples(np.ones(6), U, P, 0.0, 5), ArgumentError, "duration"),
    ("stance duration nan", lambda t: MAP.stance_samples(np.ones(6), U, P, math.nan, 5), ArgumentError, "duration"),
    ("stance duration text", lambda t: MAP.stance_samples(np.ones(6), U, P, "long", 5), ArgumentError, "duration"),
    ("stance state of 5", lambda t: MAP.stance_samples(np.ones(5), U, P, 0.1, 5), ArgumentError, "x_touchdown"),
    # -- model parameters: the problem reader's checks and messages
    ("Params m = 0", lambda t: Params(m=0), ProblemError, "params.m: must be positive, got 0 kg"),
    ("Params k = 0", lambda t: Params(k=0), ProblemError, "params.k: must be positive"),
    ("Params m = -1", lambda t: Params(m=-1), ProblemError, "params.m: must be positive, got -1 kg"),
    ("Params I nan", lambda t: Params(I=math.nan), ProblemError, "params.I: expected a finite number"),
    ("Params g text", lambda t: Params(g="9.81"), ProblemError, "params.g: expected a finite number"),
    ("Params d < 0", lambda t: Params(d=-0.01), ProblemError, "params.d: must be zero or positive"),
    ("Params rho0 None", lambda t: Params(rho0=None), ProblemError, "params.rho0"),
    ("Params k 1e9", lambda t: Params(k=1e9), ProblemError, "params.k: 1e+09 N/m exceeds the physical range"),
    ("Params m True", lambda t: Params(m=True), ProblemError, "params.m"),
    ("Params.with_ m = 0", lambda t: P.with_(m=0.0), ProblemError, "params.m"),
    # -- a gait's motion (samples = 0 crashed the interpreter)
    ("trajectory samples 0", lambda t: gait().trajectory(samples=0), ArgumentError, "samples"),
    ("trajectory samples -5", lambda t: gait().trajectory(samples=-5), ArgumentError, "samples"),
    ("trajectory strides 1.5", lambda t: gait().trajectory(strides=1.5), ArgumentError, "strides"),
    ("trajectory 1e9 x 1e9", lambda t: gait().trajectory(strides=10**9, samples=10**9), ArgumentError, "strides"),
    ("trajectory over the limit", lambda t: gait().trajectory(strides=1000, samples=100000), ArgumentError,
     "samples: 1000 strides of 100000 samples a phase make 400,000,000 samples, beyond the limit of 1,000,000"),
    ("motion params vector", lambda t: motion(MAP, X, U, P.vector()), ArgumentError, "params: expected a Params"),
    ("motion X of 3", lambda t: motion(MAP, X[:3], U, P), ArgumentError, "X"),
    ("stride_trajectory samples 1.5", lambda t: stride_trajectory(MAP, X, U, P, samples=1.5), ArgumentError,
     "samples"),
    ("TrunkRange samples 0", lambda t: TrunkRange(MAP, samples=0), ArgumentError, "samples"),
    ("Motion unknown column", lambda t: motion(MAP, X, U, P, samples=3)["bogus"], ArgumentError,
     "name: no column 'bogus'"),
    ("Motion of one column", lambda t: Motion({"t": np.zeros(1)}), ArgumentError,
     "columns: expected the 20 columns of MOTION_COLUMNS: missing stride, phase, y, z and 15 more"),
    ("Motion with a foreign column", lambda t: Motion({**motion(MAP, X, U, P, samples=3).columns, "speed": [0.0]}),
     ArgumentError, "columns: expected the 20 columns of MOTION_COLUMNS: unknown 'speed'"),
    ("Motion of ragged columns", lambda t: Motion({**motion(MAP, X, U, P, samples=3).columns, "z": np.zeros(2)}),
     ArgumentError, "columns: every column must be one-dimensional, as long as t (13 samples): not z"),
    ("Motion of a list", lambda t: Motion([1, 2]), ArgumentError, "columns: expected a dict of column name to array, got list"),
    # -- results folders
    ("open_results garbage", lambda t: open_results(t / "run"), DamagedResults, "result.json"),
    ("open_results list", lambda t: open_results(t / "run"), DamagedResults,
     "result.json: expected a JSON object, got list"),
    ("open_results null", lambda t: open_results(t / "run"), DamagedResults, "got NoneType"),
    ("open_results number", lambda t: open_results(t / "run"), DamagedResults, "got float"),
    ("open_results binary", lambda t: open_results(t / "run"), DamagedResults,
     "result.json: not UTF-8"),
    ("open_results folder", lambda t: open_results(t / "run"), DamagedResults,
     "result.json: it is a directory"),
    ("open_results deep", lambda t: open_results(t / "run"), DamagedResults,
     "result.json"),
    ("open_results NUL", lambda t: open_results("run\0x"), ArgumentError, "folder: a path cannot hold a NUL"),
    ("open_results number path", lambda t: open_results(3), ArgumentError, "folder: expected a path"),
    # -- problem mappings given from Python
    ("5000-digit integer", lambda t: parse_problem({**downward(), "params": {"m": 10**5000}}), ProblemError,
     "params.m: too large: an integer of more than 1024 bits"),
    ("nested 5000 deep", lambda t: parse_problem({**downward(), "guess": nested(5000)}), ProblemError,
     "guess.0.0.0: nested more than 32 levels"),
    ("a list that holds itself", lambda t: parse_problem({**downward(), "fix": itself()}), ProblemError,
     "fix.0.0.0: nested more than 32 levels deep (or a list that contains itself)"),
    ("replace nested", lambda t: load_problem("downward").replace(guess={"z": nested(100)}), ProblemError, "guess.z"),
    ("load_problem NUL", lambda t: load_problem("down\0ward.yaml"), ArgumentError, "path: a path cannot hold a NUL"),
    ("load_problem number", lambda t: load_problem(7), ArgumentError, "path: expected a path"),
    # -- baslip.run's options
    ("run jobs text", lambda t: run(jobs="2"), ArgumentError, "jobs: expected a whole number"),
    ("run lanes 1.5", lambda t: run(lanes=1.5), ArgumentError, "lanes"),
    ("run out number", lambda t: run(out=123), ArgumentError, "out: expected a path"),
    ("run jobs 0", lambda t: run(jobs=0), ArgumentError, "jobs: must be from 1 to 1024"),
    ("run out NUL", lambda t: run(out=str(t / "a\0b")), ArgumentError, "out: a path cannot hold a NUL"),
    ("run sources NUL", lambda t: run(out=str(t / "out"), sources="x\0y"), ArgumentError, "sources"),
    ("run scheduler number", lambda t: run(scheduler=8786), ArgumentError, "scheduler"),
    ("run fresh text", lambda t: run(fresh="yes"), ArgumentError, "fresh: expected True or False"),
    ("run problem number", lambda t: run_problem_number(), ArgumentError, "problem: expected a path"),
]


#: What the scratch folder holds before a case: result.json's bytes in run/ (None: a folder in its place).
RESULT_FILES = {
    "open_results garbage": b"{not json",
    "open_results list": b"[1, 2]",
    "open_results null": b"null",
    "open_results number": b"3.5",
    "open_results binary": b"\xff\xfe\x00\x01",
    "open_results folder": None,
    "open_results deep": b"[" * 100_000 + b"]" * 100_000,
}


def run_problem_number():
    from baslip import run as run_problem

    return run_problem(42, progress=False)


def test_the_table_covers_every_public_function_of_this_part():
    assert len(CASES) >= 60
    assert len({case[0] for case in CASES}) == len(CASES)


@pytest.mark.parametrize("case, call, error, named", CASES, ids=[case[0] for case in CASES])
def test_a_bad_argument_is_refused_by_name_and_nothing_is_written(case, call, error, named, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    if case in RESULT_FILES:
        results_folder(tmp_path, RESULT_FILES[case])
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    with pytest.raises(error) as caught:
        call(tmp_path)
    assert isinstance(caught.value, InputError)
    text = str(caught.value)
    assert named in text and "\n" not in text and len(text) < 300
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_the_calls_that_crashed_the_interpreter_raise_in_a_process_that_lives_on():
    script = """
import numpy as np
from baslip.engine.returnmap import ReturnMap
from baslip.errors import InputError
from baslip.gait.fixedpoint import FixedPointResult
from baslip.gait.ipopt_report import SolverReport
from baslip.model.dynamics import Params
from baslip.status import Status
X, U = np.array([0.4, np.pi / 2, 0.5, 0.0]), np.array([1.0, 0.1, 3.0, 0.0, 0.3])
gait = FixedPointResult("g", Status.FAILED, "", SolverReport("", 0, 0.0), Params(), X, U, None, 0.0, None, None)
for call in (lambda: ReturnMap().stance_samples(np.ones(6), U, Params(), 0.1, 0), lambda: gait.trajectory(samples=0)):
    try:
        call()
    except InputError as err:
        print(type(err).__name__, err.key)
print("alive")
"""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:3] == ["ArgumentError n", "ArgumentError samples", "alive"]


def test_a_far_too_stiff_hip_ends_the_stride_at_its_work_limit(monkeypatch):
    """Kd = 1e9 N m s/rad ran without end; its stride now ends as the named fall once the
    scout has taken the work limit's steps (lowered here so the test is quick)."""
    monkeypatch.setattr(driver, "MAX_STANCE_STEPS", 50 * driver.SCOUT_STEPS)
    rmap = ReturnMap()
    engine = rmap.compiled_engine
    calls = []
    scout = engine.functions.scout

    def counted(*args):
        calls.append(1)
        return scout(*args)

    monkeypatch.setattr(engine.functions, "scout", counted)
    stride = rmap.stride(X, [1.0, 1e9, 3.0, 0.0, 0.3], P)
    assert stride.fall is Fall.WORK_LIMIT and "work limit" in stride.fall.value
    assert len(calls) <= 50


def test_the_work_limit_leaves_a_stiff_hip_of_the_design_box_alone():
    """Kd at its bound, 100 N m s/rad, still strides on (or falls for a physical reason)."""
    stride = ReturnMap().stride(X, [1.0, 100.0, 3.0, 0.0, 0.3], P)
    assert stride.fall is not Fall.WORK_LIMIT


def test_the_trajectory_command_refuses_too_many_samples_before_solving(tmp_path, monkeypatch, capsys):
    from baslip.cli.main import trajectory

    monkeypatch.chdir(tmp_path)
    code = trajectory(["downward", "--strides", "1000", "--samples", "100000"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("error: --samples:") and "1,000,000" in err and "\n" not in err
    assert list(tmp_path.iterdir()) == []


def test_results_folders_with_a_good_record_still_open(tmp_path):
    folder = results_folder(tmp_path, json.dumps({"name": "g", "status": "converged"}).encode())
    assert open_results(folder).record["name"] == "g"
