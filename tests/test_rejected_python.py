"""Specification of rejected input through the Python API: studies and continuations built
in Python are checked exactly as the problem file's sections (tests/test_rejected_input.py).

Every bad object is refused by ``Problem.replace`` and, built into a ``Problem(...)``
directly, by ``baslip.run``: an :class:`InputError` whose message names the field, before
anything is solved or written, and with no thread or process left behind. A problem's own
values, given back, are accepted and mean the same problem.
"""

import dataclasses
import math
import os
import threading
from pathlib import Path

import pytest
from processes import descendants

import baslip
from baslip.errors import InputError
from baslip.problem.continuation import ContinuationSpec
from baslip.problem.reader import check_problem, load_problem
from baslip.problem.study import Axis, Controllers, Sweep

ROOT = Path(__file__).resolve().parents[1]
NAN, INF = math.nan, math.inf
#: The shipped problems of the BA-SLIP (those of a described model, ``model: ...``, have
#: their own reader: tests/test_model_file.py).
SHIPPED = sorted(path.stem for path in (ROOT / "problems").glob("*.yaml") if "\nmodel:" not in path.read_text())


def shipped(name: str):
    return load_problem(ROOT / "problems" / f"{name}.yaml")


def z_axis(*values) -> Axis:
    return Axis("z", values)


#: (problem, section, field, bad value, what the error must name). Each case changes one
#: field of the shipped problem's own study or continuation, as the YAML table changes one key.
FIELD_CASES = [
    # controllers
    ("controllers_downward", "study", "perturbation", (("z", NAN),), "study.perturbation.z"),
    ("controllers_downward", "study", "perturbation", (("z", INF),), "study.perturbation.z"),
    ("controllers_downward", "study", "perturbation", (("z", -0.01),), "study.perturbation.z"),
    ("controllers_downward", "study", "perturbation", (("z", 0.0),), "study.perturbation.z"),
    ("controllers_downward", "study", "perturbation", (("z", 11.0),), "study.perturbation.z"),
    ("controllers_downward", "study", "perturbation", (("z", "wide"),), "study.perturbation.z"),
    ("controllers_downward", "study", "perturbation", (("speed", 0.1),), "study.perturbation.speed"),
    ("controllers_downward", "study", "perturbation", (("z", 0.01), ("z", 0.02)), "study.perturbation"),
    ("controllers_downward", "study", "perturbation", (), "study.perturbation"),
    ("controllers_downward", "study", "perturbation", "z", "study.perturbation"),
    ("controllers_downward", "study", "samples", 10**9, "study.samples"),
    ("controllers_downward", "study", "samples", 0, "study.samples"),
    ("controllers_downward", "study", "samples", 2.5, "study.samples"),
    ("controllers_downward", "study", "samples", True, "study.samples"),
    ("controllers_downward", "study", "samples", "200", "study.samples"),
    ("controllers_downward", "study", "seed", -1, "study.seed"),
    ("controllers_downward", "study", "seed", 2**31, "study.seed"),
    ("controllers_downward", "study", "strides", 0, "study.strides"),
    ("controllers_downward", "study", "strides", None, "study.strides"),
    ("controllers_downward", "study", "tolerance", NAN, "study.tolerance"),
    ("controllers_downward", "study", "tolerance", 0.0, "study.tolerance"),
    ("controllers_downward", "study", "tolerance", 2.0, "study.tolerance"),
    ("controllers_downward", "study", "tolerance", "tight", "study.tolerance"),
    ("controllers_downward", "study", "criterion", "best", "study.criterion"),
    ("controllers_downward", "study", "lqr_scale", (("z", INF),), "study.lqr_scale.z"),
    ("controllers_downward", "study", "lqr_scale", (("x", 1.0),), "study.lqr_scale.x"),
    ("controllers_downward", "study", "boxes", (-1,), "study.boxes"),
    ("controllers_downward", "study", "boxes", (), "study.boxes"),
    ("controllers_downward", "study", "boxes", (2.0, 1.0), "study.boxes"),
    ("controllers_downward", "study", "boxes", (1.0, 1.0), "study.boxes"),
    ("controllers_downward", "study", "boxes", (NAN,), "study.boxes"),
    ("controllers_downward", "study", "boxes", tuple(range(1, 14)), "study.boxes"),
    ("controllers_downward", "study", "controllers", ("lqr",), "study.controllers"),
    ("controllers_downward", "study", "controllers", (), "study.controllers"),
    ("controllers_downward", "study", "controllers", ("feedback", "feedback"), "study.controllers"),
    ("controllers_downward", "study", "controllers", ("pivot",), "study.controllers"),  # pd has no r_vpp
    ("controllers_downward", "study", "horizon", 0, "study.horizon"),
    ("controllers_downward", "study", "horizon", 9, "study.horizon"),
    ("controllers_downward", "study", "solve_samples", (("horizon", 0),), "study.solve_samples.horizon"),
    ("controllers_downward", "study", "solve_samples", (("constant", 5),), "study.solve_samples.constant"),
    ("controllers_downward", "study", "solve_samples", -3, "study.solve_samples"),
    ("controllers_downward", "study", "kind", "basin", "study.kind"),
    # basin
    ("convergence_regions", "study", "source", "../../etc", "study.source"),
    ("convergence_regions", "study", "source", "", "study.source"),
    ("convergence_regions", "study", "source", 5, "study.source"),
    ("convergence_regions", "study", "grid", (Axis("ydot", (NAN,)), z_axis(0.4)), "study.grid.ydot"),
    ("convergence_regions", "study", "grid", (z_axis(0.4), Axis("ydot", (0.5,))), "study.grid"),
    ("convergence_regions", "study", "grid", (Axis("ydot", (0.5,)), z_axis(40.0)), "study.grid.z"),
    ("convergence_regions", "study", "grid", (Axis("ydot", tuple(0.001 * i for i in range(1, 400))),
                                              z_axis(*(0.3 + 0.001 * i for i in range(400)))), "study.grid"),
    ("convergence_regions", "study", "stable_at", (NAN, 0.4), "study.stable_at.ydot"),
    ("convergence_regions", "study", "stable_at", (0.5,), "study.stable_at"),
    ("convergence_regions", "study", "unstable_at", (0.5, 100.0), "study.unstable_at.z"),
    ("convergence_regions", "study", "strides", 0, "study.strides"),
    ("convergence_regions", "study", "tolerance", 0.0, "study.tolerance"),
    ("convergence_regions", "study", "kind", "sweep", "study.kind"),
    # sweep
    ("grid_downward", "study", "axes", (), "study.vary"),
    ("grid_downward", "study", "axes", None, "study.vary"),
    ("grid_downward", "study", "axes", (z_axis(0.4), Axis("ydot", (0.5,)), Axis("Kp", (1.0,))), "study.vary"),
    ("grid_downward", "study", "axes", (Axis("speed", (0.5,)),), "study.vary.speed"),
    ("grid_downward", "study", "axes", (z_axis(),), "study.vary.z"),
    ("grid_downward", "study", "axes", (z_axis(0.5, 0.4),), "study.vary.z"),
    ("grid_downward", "study", "axes", (z_axis(0.4, NAN),), "study.vary.z"),
    ("grid_downward", "study", "axes", (z_axis(0.4, 0.4 + 1e-14),), "study.vary.z"),
    ("grid_downward", "study", "axes", (z_axis(0.4), z_axis(0.5)), "study.vary.z"),
    ("grid_downward", "study", "axes", (Axis("z", "0.4"),), "study.vary.z"),
    ("grid_downward", "study", "axes", (z_axis(100.0),), "study.vary.z"),
    ("grid_downward", "study", "kind", "basin", "study.kind"),
    # random
    ("stable_region_random", "study", "count", -5, "study.count"),
    ("stable_region_random", "study", "count", 0, "study.count"),
    ("stable_region_random", "study", "count", 10**9, "study.count"),
    ("stable_region_random", "study", "region", "../../etc", "study.region"),
    ("stable_region_random", "study", "region", "..", "study.region"),
    ("stable_region_random", "study", "region", None, "study.region"),
    ("stable_region_random", "study", "seed", -1, "study.seed"),
    ("stable_region_random", "study", "boundary", "../b", "study.boundary"),
    ("stable_region_random", "study", "kind", "sweep", "study.kind"),
    # optimal
    ("optimal_downward", "study", "method", "newton", "study.method"),
    ("optimal_downward", "study", "starts", 0, "study.starts"),
    ("optimal_downward", "study", "starts", 10**5, "study.starts"),
    ("optimal_downward", "study", "iterations", 0, "study.iterations"),
    ("optimal_downward", "study", "seed", -1, "study.seed"),
    ("optimal_downward", "study", "axes", (), "study.vary"),
    ("optimal_downward", "study", "axes", (Axis("Kp", (1.0,)),), "study.vary.Kp"),
    # atlas
    ("atlas_downward", "study", "seeds", 0, "study.seeds"),
    ("atlas_downward", "study", "radius", 0.0, "study.radius"),
    ("atlas_downward", "study", "radius", NAN, "study.radius"),
    ("atlas_downward", "study", "max_radius", 0.1, "study.max_radius"),
    ("atlas_downward", "study", "max_charts", 0, "study.max_charts"),
    ("atlas_downward", "study", "max_spectral_radius", 0.5, "study.max_spectral_radius"),
    ("atlas_downward", "study", "plot", ("Kp", "Kp"), "study.plot"),
    ("atlas_downward", "study", "plot", ("Kp",), "study.plot"),
    ("atlas_downward", "study", "plot", ("speed", "Kp"), "study.plot"),
    ("atlas_downward", "study", "polish", -1, "study.polish"),
    ("atlas_downward", "study", "iterations", 0, "study.iterations"),
    # adaptive
    ("adaptive_upright", "study", "strides", 0, "study.strides"),
    ("adaptive_upright", "study", "strides", 10**7, "study.strides"),
    ("adaptive_upright", "study", "frozen_strides", 0, "study.frozen_strides"),
    ("adaptive_upright", "study", "perturbation", (("z", 11.0),), "study.perturbation.z"),
    ("adaptive_upright", "study", "perturbation", (("z", NAN),), "study.perturbation.z"),
    ("adaptive_upright", "study", "criterion", "x", "study.criterion"),
    ("adaptive_upright", "study", "probe_strides", 0, "study.probe_strides"),
    # continuation in one parameter
    ("continuation_downward_height", "continuation", "step", NAN, "continuation.step"),
    ("continuation_downward_height", "continuation", "step", -0.05, "continuation.step"),
    ("continuation_downward_height", "continuation", "step", 0.0, "continuation.step"),
    ("continuation_downward_height", "continuation", "step", 11.0, "continuation.step"),
    ("continuation_downward_height", "continuation", "step", INF, "continuation.step"),
    ("continuation_downward_height", "continuation", "max_points", 1, "continuation.max_points"),
    ("continuation_downward_height", "continuation", "max_points", 10**6, "continuation.max_points"),
    ("continuation_downward_height", "continuation", "max_points", 2.5, "continuation.max_points"),
    ("continuation_downward_height", "continuation", "direction", 7, "continuation.direction"),
    ("continuation_downward_height", "continuation", "direction", 0, "continuation.direction"),
    ("continuation_downward_height", "continuation", "direction", True, "continuation.direction"),
    ("continuation_downward_height", "continuation", "direction", "up", "continuation.direction"),
    ("continuation_downward_height", "continuation", "plot", "speed", "continuation.plot"),
    ("continuation_downward_height", "continuation", "switch", "fold", "continuation.switch"),
    ("continuation_downward_height", "continuation", "parameter", "speed", "continuation.parameter"),
    ("continuation_downward_height", "continuation", "lo", NAN, "continuation.range.z"),
    ("continuation_downward_height", "continuation", "hi", -INF, "continuation.range.z"),
    ("continuation_downward_height", "continuation", "lo", 0.7, "continuation.range"),
    ("continuation_downward_height", "continuation", "lo", 0.45, "continuation.range"),  # starts outside
    ("continuation_downward_height", "continuation", "follow", ("fold",), "continuation.second"),
    # curves in two parameters
    ("curve_downward_boundary", "continuation", "second", "z", "continuation.second"),
    ("curve_downward_boundary", "continuation", "second", None, "continuation.second"),
    ("curve_downward_boundary", "continuation", "second_lo", NAN, "continuation.second_range.ydot"),
    ("curve_downward_boundary", "continuation", "second_hi", 0.05, "continuation.second_range"),
    ("curve_downward_boundary", "continuation", "follow", ("hopf",), "continuation.follow"),
    ("curve_downward_boundary", "continuation", "follow", (), "continuation.follow"),
    ("curve_downward_boundary", "continuation", "starts", "some", "continuation.starts"),
    ("curve_downward_boundary", "continuation", "switch", "period_doubling", "continuation.switch"),
]


def case_id(case) -> str:
    problem, section, field, value, _ = case
    return f"{problem}.{section}.{field}={str(value)[:30]}"


def bad_object(problem, section: str, field: str, value):
    """The problem's own study or continuation with ``field`` set to ``value``."""
    return dataclasses.replace(getattr(problem, section), **{field: value})


class Untouched:
    """Holds the threads, the child processes and the folder's files from before a call,
    to show that the call left each as it was."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.threads, self.children, self.files = threading.active_count(), descendants(os.getpid()), self.listing()

    def listing(self) -> list[Path]:
        return sorted(self.folder.rglob("*"))

    def check(self) -> None:
        assert threading.active_count() == self.threads
        assert descendants(os.getpid()) == self.children
        assert self.listing() == self.files


def refused(call, names: str) -> InputError:
    """The InputError ``call`` raises, after checking that its one line names ``names``."""
    with pytest.raises(InputError) as info:
        call()
    text = str(info.value)
    assert names in text and "\n" not in text, text
    return info.value


@pytest.mark.parametrize("case", FIELD_CASES, ids=[case_id(c) for c in FIELD_CASES])
def test_a_bad_object_is_refused_by_replace_and_by_run(case, tmp_path, monkeypatch):
    name, section, field, value, names = case
    monkeypatch.chdir(tmp_path)
    problem = shipped(name)
    untouched = Untouched(tmp_path)
    refused(lambda: problem.replace(**{section: bad_object(problem, section, field, value)}), names)
    built = dataclasses.replace(problem, **{section: bad_object(problem, section, field, value)})
    refused(lambda: baslip.run(built, out=tmp_path / "out", progress=False), names)
    untouched.check()


def test_the_table_is_as_large_as_the_brief_asks():
    assert len(FIELD_CASES) >= 60
    assert {c[0] for c in FIELD_CASES} >= {"controllers_downward", "convergence_regions", "grid_downward",
                                           "stable_region_random", "optimal_downward", "atlas_downward",
                                           "adaptive_upright", "continuation_downward_height"}


def test_a_nan_perturbation_of_a_controllers_study_is_refused_before_it_runs(tmp_path):
    problem = shipped("controllers_downward")
    study = Controllers(perturbation=(("z", NAN),), samples=5, controllers=("constant",))
    built = dataclasses.replace(problem, study=study)
    error = refused(lambda: baslip.run(built, out=tmp_path / "out", progress=False), "study.perturbation.z")
    assert error.key == "study.perturbation.z" and "finite" in error.message
    assert not (tmp_path / "out").exists()


def test_a_continuation_with_a_nan_step_is_refused_before_it_runs(tmp_path):
    problem = shipped("continuation_downward_height")
    built = dataclasses.replace(problem, continuation=ContinuationSpec("z", 0.3, 0.6, step=NAN, direction="both"))
    error = refused(lambda: baslip.run(built, out=tmp_path / "out", progress=False), "continuation.step")
    assert error.key == "continuation.step"
    assert not (tmp_path / "out").exists()


def test_a_problem_built_directly_is_checked_whole_by_run(tmp_path):
    problem = dataclasses.replace(shipped("downward"), fix={"z": NAN, "ydot": 0.5})
    refused(lambda: baslip.run(problem, progress=False), "fix.z")


def test_a_study_of_another_class_kind_is_named():
    error = refused(lambda: shipped("grid_downward").replace(study=Sweep((z_axis(0.4),), kind="basin")), "study.kind")
    assert "Sweep" in error.message and "basin" in error.message


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_problem_round_trips_through_replace(name):
    problem = shipped(name)
    given_back = {f.name: getattr(problem, f.name) for f in dataclasses.fields(problem)}
    assert problem.replace(**given_back) == problem
    assert check_problem(problem) == problem


def test_a_problems_own_fix_and_open_bounds_are_accepted_back():
    problem = shipped("downward").replace(bounds={"z": [None, 0.6], "ydot": [0.1, None]})
    assert problem.replace(fix=problem.fix) == problem
    assert problem.bounds["z"] == (-INF, 0.6)
    assert problem.replace(bounds=dict(problem.bounds)) == problem
    assert problem.replace(bounds=problem.bounds, guess=problem.guess) == problem


def test_an_infinite_end_is_open_only_on_its_own_side():
    problem = shipped("downward")
    refused(lambda: problem.replace(bounds={"z": [INF, 0.6]}), "bounds.z")
    refused(lambda: problem.replace(bounds={"z": [0.3, -INF]}), "bounds.z")
    refused(lambda: problem.replace(bounds={"z": [NAN, 0.6]}), "bounds.z")
