"""Problem files of described models: ``model: path/to/file.py:Name``, or a built-in name.

A problem of a described model holds the model, what it fixes and guesses, and what to
run: its gait, a ``continuation`` in one fixed quantity, or a ``study`` of kind
``atlas``. ``model: ba-slip`` (or no ``model``) is the BA-SLIP's own problem, read by
:mod:`baslip.problem.reader` with every study kind.

Keys (values SI; a quantity in ``rad`` may be given as ``"22 deg"``, one in ``rad/s`` as
``"10 deg/s"``)::

    name: hopper
    model: models/hopper.py:HOPPER      # relative to the problem file's folder
    law: push at the bottom              # the model's first law if left out
    params: {m: 80.0, k: 20000.0}        # parameter values (the rest keep their defaults)
    fix: {z: 1.0, ydot: 5.0}             # section coordinates, controls, invariants
    guess: {theta_td: "22 deg", push: 0.01}  # no guess: from the model's reference gait
    bounds: {push: [0.0, 0.1]}
    solver: {nodes: 20, tolerance: 1.0e-10}
    continuation: {parameter: ydot, range: [3.0, 7.0], step: 0.05, max_points: 200,
                   second: k, second_range: [15000, 25000], follow: [fold]}
    study: {kind: atlas, max_charts: 200, radius: 0.2, max_radius: 0.5}
    study: {kind: controllers, grid: 9, spread: 0.2, strides: 30}
    study: {kind: sweep, sweep: {ydot: {from: 3.0, to: 7.0, count: 9}, z: [0.9, 1.0, 1.1]}}
"""

from __future__ import annotations

import importlib.util
import math
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from baslip.errors import ArgumentError, ProblemError
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.catalogue.slip import SLIP
from baslip.model.catalogue.walker import WALKER
from baslip.model.description import Model, ModelError
from baslip.model.sizes import similarity
from baslip.model.symbolic import model_functions
from baslip.problem.modelspec import ModelSpec
from baslip.problem.reader import BA_SLIP_NAME, Problem, parse_problem
from baslip.problem.source import read_problem_file
from baslip.problem.text import check_plain_data, excerpt
from baslip.problem.values import mapping
from baslip.problem.values import number as plain_number

#: The described models baslip ships, by the name a problem gives them.
#: ``ba-slip-described`` is the BA-SLIP's description on the generic engine, with the
#: virtual-constraint law that only it has (``ba-slip`` is the compiled BA-SLIP's problem).
BUILT_IN = {"slip": SLIP, "walker": WALKER, "ba-slip-described": BA_SLIP}
TOP_LEVEL_KEYS = ("name", "model", "law", "params", "fix", "guess", "bounds", "solver", "continuation", "study")
SOLVER_KEYS = ("nodes", "tolerance")
CONTINUATION_KEYS = ("parameter", "range", "step", "max_points", "second", "second_range", "follow")
#: The bifurcation curves a continuation may follow in a second parameter.
CURVE_KINDS = ("fold", "period_doubling", "neimark_sacker")
STUDY_KEYS = ("kind", "max_charts", "radius", "max_radius", "plot", "grid", "spread", "strides", "sweep")
#: The keys of each study kind of a described model.
KIND_KEYS = {"atlas": ("kind", "max_charts", "radius", "max_radius", "plot"),
             "controllers": ("kind", "grid", "spread", "strides"), "sweep": ("kind", "sweep")}
#: Most points of a described model's sweep.
MAX_SWEEP_POINTS = 10_000
#: Angles and angular rates given with a unit, as a factor to SI.
UNITS = {"rad": {"deg": math.pi / 180, "rad": 1.0}, "rad/s": {"deg/s": math.pi / 180, "rad/s": 1.0}}


@dataclass(frozen=True)
class ModelContinuation:
    """A branch in the fixed quantity ``parameter`` over [low, high] (its unit), and the
    bifurcation curves of kinds ``follow`` from its first special point of each kind, in
    (``parameter``, ``second``) over ``second_range``."""

    parameter: str
    low: float
    high: float
    step: float = 0.02
    max_points: int = 200
    second: str = ""
    second_range: tuple[float, float] = (0.0, 0.0)
    follow: tuple[str, ...] = ()


@dataclass(frozen=True)
class ModelAtlasStudy:
    """An atlas of the gaits in the free quantities: charts at most, the first and
    largest radius of a chart (in units of each quantity's size at the gait), and the two
    free quantities of its figure (the first two free ones if empty)."""

    max_charts: int = 200
    radius: float = 0.2
    max_radius: float = 0.5
    plot: tuple[str, ...] = ()


@dataclass(frozen=True)
class ModelControllersStudy:
    """The gait's stride-to-stride controllers compared by their measured basins: starts
    on a ``grid`` x ``grid`` square within ``spread`` (relative) of the gait's first two
    section coordinates its law's invariants leave free, on their level
    (:func:`baslip.analysis.modelcontrol.grid_starts`), each run ``strides`` strides."""

    grid: int = 9
    spread: float = 0.2
    strides: int = 30


@dataclass(frozen=True)
class ModelSweepStudy:
    """Gaits on a grid of one or two fixed quantities: each name's values, in its unit.
    Each point starts from its solved neighbour (warm start) and is verified."""

    axes: tuple[tuple[str, tuple[float, ...]], ...]

    @property
    def points(self) -> int:
        """How many gaits the grid asks for."""
        count = 1
        for _, values in self.axes:
            count *= len(values)
        return count


@dataclass(frozen=True)
class ModelProblem:
    """A validated problem of a described model."""

    name: str
    model_source: str
    spec: ModelSpec
    continuation: ModelContinuation | None = None
    atlas: ModelAtlasStudy | None = None
    controllers: ModelControllersStudy | None = None
    sweep: ModelSweepStudy | None = None
    #: No ``guess``: every section coordinate and control not fixed is free, and the solve
    #: starts from the model's reference gait carried to the problem.
    from_reference: bool = False

    def to_dict(self) -> dict:
        """The problem as plain data (SI units), for a result's provenance."""
        spec = self.spec
        record: dict[str, Any] = {
            "name": self.name, "model": self.model_source, "law": spec.model.law(spec.law).name,
            "fix": dict(spec.fixed), "guess": dict(spec.guess), "bounds": {k: list(v) for k, v in spec.bounds.items()},
            "solver": {"nodes": spec.nodes, "tolerance": spec.tolerance},
        }
        if self.continuation is not None:
            record["continuation"] = {k: list(v) if isinstance(v, tuple) else v
                                      for k, v in vars(self.continuation).items()}
        if self.atlas is not None:
            record["study"] = {"kind": "atlas", **vars(self.atlas)}
        if self.controllers is not None:
            record["study"] = {"kind": "controllers", **vars(self.controllers)}
        if self.sweep is not None:
            record["study"] = {"kind": "sweep", "sweep": {name: list(values) for name, values in self.sweep.axes}}
        if self.from_reference:
            record["start"] = "the model's reference gait, carried to the problem"
        return record


def load_any_problem(path: str | Path) -> Problem | ModelProblem:
    """Read a problem file of the BA-SLIP or of a described model.

    Raises
    ------
    ProblemError
        If anything is invalid; its ``key`` names the offending entry (``model`` for a
        model that cannot be loaded, ``model.<part>`` for a description that cannot run).
    """
    data, name, where = read_problem_file(path)
    if isinstance(data, Mapping) and data.get("model", BA_SLIP_NAME) != BA_SLIP_NAME:
        return parse_model_problem(data, name, where.parent)
    if isinstance(data, Mapping):
        data = {k: v for k, v in data.items() if k != "model"}
    return parse_problem(data, default_name=name)


def load_model(reference: Any, folder: Path) -> Model:
    """The model a problem names: a built-in one (a key of :data:`BUILT_IN`) or
    ``file.py:Name``, the file relative to ``folder``."""
    if not isinstance(reference, str):
        raise ProblemError("model", f"expected a model's name or file.py:Name, got {excerpt(reference)}")
    if reference in BUILT_IN:
        return BUILT_IN[reference]
    match = re.fullmatch(r"(.+\.py):([A-Za-z_][A-Za-z0-9_]*)", reference)
    if not match:
        raise ProblemError("model", f"{excerpt(reference)} is neither a built-in model "
                                    f"({', '.join([BA_SLIP_NAME, *BUILT_IN])}) nor file.py:Name")
    file = (folder / match.group(1)).resolve()
    if not file.is_file():
        raise ProblemError("model", f"no such model file: {file}")
    module = _import(file)
    model = getattr(module, match.group(2), None)
    if not isinstance(model, Model):
        found = "nothing" if model is None else type(model).__name__
        raise ProblemError("model", f"{match.group(2)} in {file.name} is {found}, not a baslip Model")
    return model


def _import(file: Path):
    """The module of a model file, imported under a name of its own."""
    name = f"baslip_user_model_{abs(hash(str(file)))}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, file)
    if spec is None or spec.loader is None:
        raise ProblemError("model", f"cannot import {file}")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as err:  # the user's code: any error is theirs, said in one line
        raise ProblemError("model", f"importing {file.name} raised {type(err).__name__}: {err}") from None
    sys.modules[name] = module
    return module


def parse_model_problem(data: Any, default_name: str = "problem", folder: Path = Path(".")) -> ModelProblem:
    """Validate a described model's problem given as plain data (as read from YAML).

    Parameters
    ----------
    data : Any
        The problem file's top-level keys and values.
    default_name : str
        The name when ``data`` has no ``name``.
    folder : Path
        Where a model file's path starts.
    """
    check_plain_data(data)
    top = mapping(data, "", TOP_LEVEL_KEYS)
    model = load_model(top.get("model"), folder)
    law = top.get("law")
    try:
        law_name = model.law(law).name if law is None or isinstance(law, str) else None
    except ModelError as err:
        raise ProblemError("law", err.message) from None
    if law_name is None:
        raise ProblemError("law", f"expected a law's name, got {excerpt(law)}")
    model_functions(model, law_name)  # a description that cannot run is refused here, naming the part
    fixed = {**_values(top.get("params", {}), "params", model, law_name),
             **_values(top.get("fix", {}), "fix", model, law_name)}
    from_reference = "guess" not in top
    guess = _values(top["guess"], "guess", model, law_name) if not from_reference else _unguessed(model, law_name, fixed)
    solver = mapping(top.get("solver", {}), "solver", SOLVER_KEYS)
    spec = _spec(model, law_name, fixed, guess, _bounds(top.get("bounds", {}), model, law_name), solver)
    name = top.get("name", default_name)
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        raise ProblemError("name", f"expected a plain name (letters, digits, _ . -), got {excerpt(name)}")
    study = _study(top.get("study"), spec)
    return ModelProblem(name, str(top["model"]), spec, _continuation(top.get("continuation"), spec),
                        study if isinstance(study, ModelAtlasStudy) else None,
                        study if isinstance(study, ModelControllersStudy) else None,
                        study if isinstance(study, ModelSweepStudy) else None, from_reference)


def _unguessed(model: Model, law: str, fixed: dict[str, float]) -> dict[str, float]:
    """With no guess: every section coordinate and control not fixed is free, at its
    reference value (or default), scaled to the problem's body (:mod:`baslip.model.sizes`),
    until the reference gait is carried to the problem."""
    if not model.reference or model.law(law).name != model.laws[0].name:
        raise ProblemError("guess", f"model {model.name} names no reference gait under this law to start from: "
                                    "give a guess")
    scale = similarity(model, {q.name: fixed.get(q.name, q.default) for q in model.parameters})
    defaults = {q.name: q.default for q in model.controls_of(law)}
    names = (*model.section.coordinates, *defaults)
    return {n: float(model.reference.get(n, defaults.get(n, 0.0))) * scale.factor(model.dimension(n, law))
            for n in names if n not in fixed}


def _value(value: Any, key: str, unit: str) -> float:
    if isinstance(value, str) and unit in UNITS:
        match = re.fullmatch(r"\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*([a-z/]+)\s*", value)
        if match and match.group(2) in UNITS[unit]:
            return float(match.group(1)) * UNITS[unit][match.group(2)]
    return plain_number(value, key)


def _values(value: Any, key: str, model: Model, law: str) -> dict[str, float]:
    names = (*model.section.coordinates, *(q.name for q in model.quantities(law)),
             *(i.name for i in model.invariants_of(law)))
    allowed = tuple(q.name for q in model.parameters) if key == "params" else names
    given = mapping(value, key, allowed)
    return {name: _value(v, f"{key}.{name}", model.unit(name, law)) for name, v in given.items()}


def _bounds(value: Any, model: Model, law: str) -> dict[str, tuple[float, float]]:
    names = (*model.section.coordinates, *(q.name for q in model.quantities(law)))
    bounds = {}
    for name, pair in mapping(value, "bounds", names).items():
        if not isinstance(pair, list) or len(pair) != 2:
            raise ProblemError(f"bounds.{name}", f"expected [low, high], got {excerpt(pair)}")
        low, high = (_value(v, f"bounds.{name}", model.unit(name, law)) for v in pair)
        if not low < high:
            raise ProblemError(f"bounds.{name}", f"the low end {low} must lie below the high end {high}")
        bounds[name] = (low, high)
    return bounds


def _spec(model: Model, law: str, fixed: dict, guess: dict, bounds: dict, solver: dict) -> ModelSpec:
    nodes = solver.get("nodes", 20)
    tolerance = plain_number(solver.get("tolerance", 1e-10), "solver.tolerance")
    if isinstance(nodes, bool) or not isinstance(nodes, int):
        raise ProblemError("solver.nodes", f"expected an integer, got {excerpt(nodes)}")
    try:
        return ModelSpec(model, law, fixed, guess, bounds, nodes, tolerance)
    except ArgumentError as err:
        raise ProblemError(_problem_key(err.key), err.message) from None


def _problem_key(key: str) -> str:
    """The problem file's key for a :class:`ModelSpec` argument's."""
    head, _, rest = key.partition(".")
    if head == "fixed":
        return f"fix.{rest}"
    if head in ("guess", "bounds"):
        return key
    if head in ("nodes", "tolerance"):
        return f"solver.{head}"
    return f"guess.{key}" if key else "guess"


def _continuation(value: Any, spec: ModelSpec) -> ModelContinuation | None:
    if value is None:
        return None
    given = mapping(value, "continuation", CONTINUATION_KEYS)
    parameter = given.get("parameter")
    if not isinstance(parameter, str) or parameter not in spec.fixed:
        raise ProblemError("continuation.parameter", f"expected a fixed quantity of the problem, "
                                                     f"got {excerpt(parameter)} (fixed: {', '.join(spec.fixed)})")
    bounds = given.get("range")
    if not isinstance(bounds, list) or len(bounds) != 2:
        raise ProblemError("continuation.range", f"expected [low, high], got {excerpt(bounds)}")
    unit = spec.model.unit(parameter, spec.law)
    low, high = (_value(v, "continuation.range", unit) for v in bounds)
    if not low < spec.fixed[parameter] < high:
        raise ProblemError("continuation.range", f"must hold the fixed {parameter} = {spec.fixed[parameter]:g} "
                                                 f"strictly inside [{low:g}, {high:g}]")
    step = plain_number(given.get("step", 0.02), "continuation.step")
    points = given.get("max_points", 200)
    if not 0 < step <= 1:
        raise ProblemError("continuation.step", f"must lie in (0, 1] (scaled units), not {step:g}")
    if isinstance(points, bool) or not isinstance(points, int) or not 2 <= points <= 10_000:
        raise ProblemError("continuation.max_points", f"expected an integer in [2, 10000], got {excerpt(points)}")
    return ModelContinuation(parameter, low, high, step, points, *_curves(given, spec, parameter))


def _curves(given: dict, spec: ModelSpec, parameter: str) -> tuple[str, tuple[float, float], tuple[str, ...]]:
    """The curves' second parameter, its range and the kinds followed (none if not asked)."""
    asked = [key for key in ("second", "second_range", "follow") if key in given]
    if not asked:
        return "", (0.0, 0.0), ()
    if len(asked) < 3:
        missing = [key for key in ("second", "second_range", "follow") if key not in given]
        raise ProblemError(f"continuation.{missing[0]}", "second, second_range and follow come together")
    second = given["second"]
    if second == parameter or second not in spec.fixed:
        raise ProblemError("continuation.second", f"expected a fixed quantity other than {parameter}, "
                                                  f"got {excerpt(second)} (fixed: {', '.join(spec.fixed)})")
    bounds = given["second_range"]
    if not isinstance(bounds, list) or len(bounds) != 2:
        raise ProblemError("continuation.second_range", f"expected [low, high], got {excerpt(bounds)}")
    low, high = (_value(v, "continuation.second_range", spec.model.unit(second, spec.law)) for v in bounds)
    if not low < spec.fixed[second] < high:
        raise ProblemError("continuation.second_range", f"must hold the fixed {second} = {spec.fixed[second]:g} "
                                                        f"strictly inside [{low:g}, {high:g}]")
    follow = given["follow"]
    if not isinstance(follow, list) or not follow or any(k not in CURVE_KINDS for k in follow) or \
            len(set(follow)) != len(follow):
        raise ProblemError("continuation.follow", f"expected a list of distinct curve kinds ({', '.join(CURVE_KINDS)}), "
                                                  f"got {excerpt(follow)}")
    return second, (low, high), tuple(follow)


def _study(value: Any, spec: ModelSpec) -> ModelAtlasStudy | ModelControllersStudy | ModelSweepStudy | None:
    if value is None:
        return None
    kind = mapping(value, "study", STUDY_KEYS).get("kind")
    if kind not in KIND_KEYS:
        raise ProblemError("study.kind", f"{excerpt(kind)}: a described model's problem runs a gait, a continuation "
                                         "or a study of kind atlas, controllers or sweep (the other kinds are the "
                                         "BA-SLIP's)")
    given = mapping(value, "study", KIND_KEYS[kind])
    if kind == "controllers":
        return _controllers_study(given)
    if kind == "sweep":
        return _sweep_study(given, spec)
    charts = given.get("max_charts", 200)
    if isinstance(charts, bool) or not isinstance(charts, int) or not 1 <= charts <= 100_000:
        raise ProblemError("study.max_charts", f"expected an integer in [1, 100000], got {excerpt(charts)}")
    radius = plain_number(given.get("radius", 0.2), "study.radius")
    if not 0 < radius <= 10:
        raise ProblemError("study.radius", f"must lie in (0, 10], not {radius:g}")
    largest = plain_number(given.get("max_radius", max(0.5, radius)), "study.max_radius")
    if not radius <= largest <= 10:
        raise ProblemError("study.max_radius", f"must lie in [radius, 10], not {largest:g}")
    plot = given.get("plot", [])
    if not isinstance(plot, list) or (plot and (len(plot) != 2 or len(set(plot)) != 2 or
                                                any(name not in spec.free for name in plot))):
        raise ProblemError("study.plot", f"expected two different free quantities ({', '.join(spec.free)}), "
                                         f"got {excerpt(plot)}")
    return ModelAtlasStudy(charts, radius, largest, tuple(plot))


def _controllers_study(given: dict) -> ModelControllersStudy:
    grid, strides = given.get("grid", 9), given.get("strides", 30)
    for key, count, most in (("grid", grid, 101), ("strides", strides, 10_000)):
        if isinstance(count, bool) or not isinstance(count, int) or not 2 <= count <= most:
            raise ProblemError(f"study.{key}", f"expected an integer in [2, {most}], got {excerpt(count)}")
    spread = plain_number(given.get("spread", 0.2), "study.spread")
    if not 0 < spread < 1:
        raise ProblemError("study.spread", f"must lie in (0, 1) (relative to the gait), not {spread:g}")
    return ModelControllersStudy(grid, spread, strides)


def _sweep_study(given: dict, spec: ModelSpec) -> ModelSweepStudy:
    """``sweep: {name: [values] or {from, to, count}}`` over one or two fixed quantities."""
    sweep = given.get("sweep")
    if not isinstance(sweep, Mapping) or not 1 <= len(sweep) <= 2:
        raise ProblemError("study.sweep", f"expected a mapping of one or two fixed quantities to their values, "
                                          f"got {excerpt(sweep)}")
    axes = []
    for name, values in sweep.items():
        key = f"study.sweep.{name}"
        if name not in spec.fixed or name in spec.fixed_invariants:
            raise ProblemError(key, f"expected a fixed quantity of the problem ({', '.join(spec.fixed)})")
        unit = spec.model.unit(name, spec.law)
        if isinstance(values, Mapping):
            spaced = mapping(values, key, ("from", "to", "count"))
            count = spaced.get("count")
            if isinstance(count, bool) or not isinstance(count, int) or count < 2:
                raise ProblemError(f"{key}.count", f"expected an integer of at least 2, got {excerpt(count)}")
            low_end, high_end = (_value(spaced.get(end), f"{key}.{end}", unit) for end in ("from", "to"))
            numbers = tuple(float(v) for v in np.linspace(low_end, high_end, count))
        elif isinstance(values, list) and values:
            numbers = tuple(_value(v, key, unit) for v in values)
        else:
            raise ProblemError(key, f"expected a list of values or {{from, to, count}}, got {excerpt(values)}")
        low, high = spec.range_of(name)
        outside = [v for v in numbers if not low <= v <= high]
        if outside:
            raise ProblemError(key, f"{outside[0]:g} lies outside {name}'s range [{low:g}, {high:g}]")
        axes.append((name, numbers))
    study = ModelSweepStudy(tuple(axes))
    if study.points > MAX_SWEEP_POINTS:
        raise ProblemError("study.sweep", f"asks for {study.points:,} gaits; at most {MAX_SWEEP_POINTS:,}")
    return study
