"""The ``study:`` section of a problem file, validated into frozen dataclasses.

Kinds:

* ``sweep``: fixed points over a grid of one or two quantities,
  ``vary: {ydot: [start, stop, step], z: [start, stop, step]}`` (both ends included);
* ``random``: ``count`` fixed points at random values of the two quantities of a finished
  sweep (``region``), inside its stable region: the region interpolated from the grid, or,
  with ``boundary``, inside the stability boundary traced by a finished continuation in
  those two quantities (:mod:`baslip.studies.boundary`); ``seed`` makes the draw repeatable;
* ``basin``: convergence regions, by simulation, of the stable fixed points of a finished
  sweep (``source``) over a ``grid`` of (ydot, z) apex states; ``stable_at`` and
  ``unstable_at`` pick the example points; ``strides`` and ``tolerance`` decide convergence;
* ``adaptive``: re-solve the control at every apex for ``strides`` strides from the
  problem's fixed point, then hold the last control for at most ``frozen_strides``;
* ``optimal``: at every point of a grid of one or two quantities (``vary``, as a sweep),
  ``starts`` fixed points with gains drawn over their whole bounds, each followed by a
  descent of at most ``iterations`` steps to the least spectral radius nearby
  (:mod:`baslip.analysis.descent`), or with ``method: schur_nlp`` by the stability NLP
  (:mod:`baslip.gait.monodromy`, at most the problem's ``solver.max_iter`` IPOPT
  iterations); ``seed`` makes the draws repeatable;
* ``atlas``: at every point of a grid of one or two quantities (``vary``), the manifold of
  fixed points covered by charts (:mod:`baslip.analysis.atlas`), grown from ``seeds``
  independent solves with gains drawn over their whole bounds; ``radius`` and
  ``max_radius`` size the charts (atlas units), ``max_charts`` caps each cell,
  ``max_spectral_radius`` stops the covering at charts more unstable than it, and
  ``plot`` names the two quantities of its figure; ``polish`` descents of at most
  ``iterations`` steps each start from the least local minima of the radius;
* ``families``: which gaits exist at the problem's own cell and the most stable one: an
  atlas of that one cell with a short budget (its keys are the atlas's but ``vary``),
  answered with the pieces found, the best gait and how wide the search was
  (:mod:`baslip.studies.families`).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

from baslip.errors import ProblemError
from baslip.model.quantities import ANY_DESIGN
from baslip.problem.text import NonScalarKey, clip, excerpt
from baslip.problem.values import number

#: Decimals to which swept values are rounded (they key a study's rows).
VALUE_DECIMALS = 12
#: Most values along one axis of a sweep or a basin grid.
MAX_AXIS_VALUES = 100_000
#: Most apex states in a basin grid (each is simulated from every stable point).
MAX_GRID_STATES = 100_000
#: Smallest size in a map of apex sizes (a perturbation, an LQR scale): its inverse square
#: must stay a finite number.
MIN_SIZE = 1e-12
#: The gains an optimal study draws at random for every start, so that it cannot sweep them.
DRAWN_GAINS = ("Kp", "Kd")


class StudyError(ProblemError):
    """An invalid study section; ``key`` is the dotted path of the offending entry."""


@dataclass(frozen=True)
class Axis:
    """One swept quantity and its values (SI units and radians)."""

    name: str
    values: tuple[float, ...]


@dataclass(frozen=True)
class Sweep:
    """``kind: sweep``: fixed points over a grid of one or two quantities (``axes``, SI
    units and radians), one solve per grid point."""

    axes: tuple[Axis, ...]
    kind: str = "sweep"


@dataclass(frozen=True)
class RandomSample:
    """``kind: random``: ``count`` points drawn (with ``seed``) inside the stable region of
    the finished two-quantity sweep ``region``, or inside the stability boundary traced by
    the finished curve run ``boundary``; each is solved and verified."""

    region: str  # name of a finished two-quantity sweep
    count: int
    seed: int = 0
    boundary: str | None = None  # name of a finished curve run: sample inside its boundary
    kind: str = "random"


@dataclass(frozen=True)
class Basin:
    """``kind: basin``: the convergence regions, by simulation, of a stable and an unstable
    point of the finished (ydot, z) sweep ``source``. ``grid`` holds the initial apexes'
    ydot [m/s] and z [m]; ``stable_at`` and ``unstable_at`` are (ydot [m/s], z [m]) near
    the two examples; a start has converged when it comes within ``tolerance`` (relative
    distance) of the fixed point in at most ``strides`` strides."""

    source: str  # name of a finished (ydot, z) sweep
    grid: tuple[Axis, Axis]  # ydot and z of the initial apex states
    stable_at: tuple[float, float]  # (ydot, z) near the stable example
    unstable_at: tuple[float, float]  # (ydot, z) near the unstable example
    strides: int = 40
    tolerance: float = 1e-6
    kind: str = "basin"


@dataclass(frozen=True)
class Adaptive:
    """``kind: adaptive``: from the gait perturbed by ``perturbation`` (apex quantity ->
    offset, SI units and radians), the control re-solved at every apex for ``strides``
    strides by ``criterion``, then held for at most ``frozen_strides``; a perturbed start
    counts as recovered when it survives ``probe_strides`` strides."""

    strides: int = 2048
    frozen_strides: int = 1000
    perturbation: tuple[tuple[str, float], ...] = ()  # offsets of the first apex from the gait
    criterion: str = "thesis"  # "thesis": next apex near the current one; "tracking": near the gait
    probe_strides: int = 200  # strides a perturbed start must survive to count as recovered
    kind: str = "adaptive"


@dataclass(frozen=True)
class Optimal:
    """``kind: optimal``: the most stable gait at each cell of ``axes``, descended (``method``:
    ``descent`` along the fixed-point manifold, or ``schur_nlp``, the stability NLP) from
    ``starts`` gaits whose gains (or pivot) are drawn with ``seed`` over their bounds; each
    descent takes at most ``iterations`` quasi-Newton steps."""

    axes: tuple[Axis, ...]
    starts: int = 16
    seed: int = 0
    iterations: int = 60  # most quasi-Newton iterations of each descent
    method: str = "descent"  # or "schur_nlp": the stability NLP from each start (OPTIMAL_METHODS)
    kind: str = "optimal"


@dataclass(frozen=True)
class Atlas:
    """``kind: atlas``: the family of gaits at each cell of ``axes`` covered by charts
    (:mod:`baslip.analysis.atlas`), grown from ``seeds`` independent solves. Radii are in
    atlas units (:mod:`baslip.analysis.gaitatlas`); ``plot`` names the figure's two
    quantities; ``polish`` descents of at most ``iterations`` steps each polish the least
    local minima of the spectral radius. docs/guides/problem-files.md gives each key's
    range."""

    axes: tuple[Axis, ...]  # the cells: one atlas at each grid point
    seeds: int = 24  # solves per cell (the guess's, then drawn gains), each seeding a piece unless on a covered one
    seed: int = 0
    radius: float = 0.3  # of a piece's first chart, in atlas units (baslip.analysis.gaitatlas)
    max_radius: float = 1.5
    max_charts: int = 3000  # per cell
    max_spectral_radius: float | None = None  # charts above it are made but not grown from (None: no cap)
    plot: tuple[str, ...] = ("Kp", "Kd")  # two quantities
    polish: int = 3  # stability descents per cell, from the least local minima of the radius (0: none)
    iterations: int = 60  # most quasi-Newton iterations of each polishing descent
    compass_trials: int = 600  # most trials of the compass search that then continues each descent
    kind: str = "atlas"


@dataclass(frozen=True)
class Families(Atlas):
    """``kind: families``: which gaits exist at the problem's own cell (its fixed values),
    and the most stable one: an atlas of that one cell (:class:`Atlas`, whose keys it
    takes but ``vary``) with a short budget, answered by
    :mod:`baslip.studies.families`. Its ``axes`` are empty: the cell is the problem's."""

    axes: tuple[Axis, ...] = ()
    plot: tuple[str, ...] = ()  # the figure's two quantities; () for the first two free ones, gains first
    seeds: int = 6
    max_charts: int = 120
    polish: int = 2
    iterations: int = 20
    compass_trials: int = 40
    kind: str = "families"


@dataclass(frozen=True)
class Controllers:
    """``kind: controllers``: stride-to-stride controllers compared by their measured
    basins. ``perturbation`` gives the basin box's half-width per apex quantity (SI units
    and radians) and ``boxes`` its sizes as multiples of it; ``samples`` starts a box
    (drawn with ``seed``) run at most ``strides`` strides, and a start has returned when it
    comes within ``tolerance`` (relative distance) of the gait. docs/guides/problem-files.md
    gives each key's range."""

    perturbation: tuple[tuple[str, float], ...]  # half-width of the box in each apex quantity
    samples: int = 200
    seed: int = 0
    strides: int = 100
    tolerance: float = 1e-3
    criterion: str = "tracking"  # of the per-stride re-solve: "thesis" or "tracking"
    lqr_scale: tuple[tuple[str, float], ...] = ()  # fixed LQR weights (apex deviation costing as much as a
    # nominal control change); without them the tool chooses the weights
    boxes: tuple[float, ...] = (1.0,)  # multiples of the perturbation's half-widths: one basin box each
    controllers: tuple[str, ...] = ("constant", "feedback", "horizon", "resolve")  # some of CONTROLLER_KINDS
    horizon: int = 2  # strides planned by the receding-horizon re-solve
    # Starts per box of each re-solving controller (horizon, resolve) that runs fewer than
    # ``samples``: a re-solve costs Jacobian strides at every apex, a batched run a few values.
    solve_samples: tuple[tuple[str, int], ...] = ()
    kind: str = "controllers"

    def starts(self, controller: str) -> int:
        """Starts per box of ``controller``: ``samples``, or fewer for a re-solving one
        given its own count in ``solve_samples`` (the first of the same draws)."""
        return min(dict(self.solve_samples).get(controller, self.samples), self.samples)


Study = Sweep | RandomSample | Basin | Adaptive | Optimal | Controllers | Atlas | Families
#: The study classes, for ``isinstance``.
STUDY_KINDS = (Sweep, RandomSample, Basin, Adaptive, Optimal, Controllers, Atlas, Families)
KINDS = ("sweep", "random", "basin", "adaptive", "optimal", "controllers", "atlas", "families")
#: The keys each study kind accepts (docs/guides/problem-files.md documents each).
STUDY_KEYS = {
    "sweep": ("kind", "vary"),
    "random": ("kind", "region", "count", "seed", "boundary"),
    "basin": ("kind", "source", "grid", "stable_at", "unstable_at", "strides", "tolerance"),
    "adaptive": ("kind", "strides", "frozen_strides", "perturbation", "criterion", "probe_strides"),
    "optimal": ("kind", "vary", "starts", "seed", "iterations", "method"),
    "controllers": ("kind", "perturbation", "samples", "seed", "strides", "tolerance", "criterion", "lqr_scale",
                    "boxes", "controllers", "horizon", "solve_samples"),
    "atlas": ("kind", "vary", "seeds", "seed", "radius", "max_radius", "max_charts", "max_spectral_radius", "plot",
              "polish", "iterations", "compass_trials"),
    "families": ("kind", "seeds", "seed", "radius", "max_radius", "max_charts", "max_spectral_radius", "plot",
                 "polish", "iterations", "compass_trials"),
}


def parse_study(data) -> Study:
    """Validate a ``study`` mapping, or a study object built in Python, into its frozen
    dataclass; an object is checked as its mapping form (:func:`study_mapping`) would be."""
    if isinstance(data, STUDY_KINDS):
        data = study_mapping(data)
    if not isinstance(data, dict):
        raise StudyError("study", f"expected a mapping, got {type(data).__name__}")
    kind = data.get("kind")
    if not isinstance(kind, str) or kind not in KINDS:
        raise StudyError("study.kind", f"expected one of {', '.join(KINDS)}, got {excerpt(kind)}")
    allowed = STUDY_KEYS[kind]
    for key in data:
        if isinstance(key, NonScalarKey):
            raise StudyError(f"study.{key}", f"a key must be a plain name, not a {key.kind}")
        if key not in allowed:
            raise StudyError(f"study.{clip(str(key))}", f"unknown key for a {kind} study (expected one of {', '.join(allowed)})")
    if kind in ("sweep", "optimal", "atlas"):
        axes = _axes(data.get("vary"), "study.vary", ANY_DESIGN)
        if not 1 <= len(axes) <= 2:
            raise StudyError("study.vary", f"expected one or two quantities, got {len(axes)}")
        if kind == "sweep":
            return Sweep(axes)
        if kind == "atlas":
            return _atlas(data, axes)
        for axis in axes:
            if axis.name in DRAWN_GAINS:
                raise StudyError(f"study.vary.{axis.name}", f"an optimal study draws {axis.name} at random for every "
                                 f"start ({', '.join(DRAWN_GAINS)}), so it cannot sweep it; fix it or sweep another quantity")
        if data.get("method") == "schur_nlp" and "iterations" in data:
            raise StudyError("study.iterations", "counts descent steps; with method schur_nlp the problem's "
                             "solver.max_iter bounds IPOPT's iterations")
        return Optimal(
            axes,
            starts=_integer(data.get("starts", 16), "study.starts", 1, 10000),
            seed=_integer(data.get("seed", 0), "study.seed", 0, 2**31 - 1),
            iterations=_integer(data.get("iterations", 60), "study.iterations", 1, 10000),
            method=_method(data.get("method", "descent")),
        )
    if kind == "families":
        return _atlas(data, (), Families)
    if kind == "random":
        return RandomSample(
            region=_name(data.get("region"), "study.region"),
            count=_integer(data.get("count"), "study.count", 1, 100000),
            seed=_integer(data.get("seed", 0), "study.seed", 0, 2**31 - 1),
            boundary=_name(data["boundary"], "study.boundary") if "boundary" in data else None,
        )
    if kind == "basin":
        grid = _axes(data.get("grid"), "study.grid", ("ydot", "z"))
        if tuple(a.name for a in grid) != ("ydot", "z"):
            raise StudyError("study.grid", "expected ydot and z, in that order")
        states = len(grid[0].values) * len(grid[1].values)
        if states > MAX_GRID_STATES:
            raise StudyError("study.grid", f"{len(grid[0].values)} x {len(grid[1].values)} = {states} apex states is "
                             f"more than {MAX_GRID_STATES}")
        return Basin(
            source=_name(data.get("source"), "study.source"),
            grid=(grid[0], grid[1]),
            stable_at=_pair(data.get("stable_at"), "study.stable_at"),
            unstable_at=_pair(data.get("unstable_at"), "study.unstable_at"),
            strides=_integer(data.get("strides", 40), "study.strides", 1, 100000),
            tolerance=_fraction(data.get("tolerance", 1e-6), "study.tolerance"),
        )
    if kind == "controllers":
        criterion = _criterion(data.get("criterion", "tracking"))
        return Controllers(
            perturbation=_apex_map(data.get("perturbation"), "study.perturbation", positive=True, required=True),
            samples=_integer(data.get("samples", 200), "study.samples", 1, 100000),
            seed=_integer(data.get("seed", 0), "study.seed", 0, 2**31 - 1),
            strides=_integer(data.get("strides", 100), "study.strides", 1, 100000),
            tolerance=_fraction(data.get("tolerance", 1e-3), "study.tolerance"),
            criterion=criterion,
            lqr_scale=_apex_map(data.get("lqr_scale", {}), "study.lqr_scale", positive=True),
            boxes=_boxes(data.get("boxes", [1.0])),
            controllers=_controller_names(data.get("controllers", list(Controllers.controllers))),
            horizon=_integer(data.get("horizon", 2), "study.horizon", 1, 8),
            solve_samples=_solve_samples(data.get("solve_samples")),
        )
    return Adaptive(
        strides=_integer(data.get("strides", 2048), "study.strides", 1, 1000000),
        frozen_strides=_integer(data.get("frozen_strides", 1000), "study.frozen_strides", 1, 1000000),
        perturbation=_apex_map(data.get("perturbation", {}), "study.perturbation", positive=False),
        criterion=_criterion(data.get("criterion", "thesis")),
        probe_strides=_integer(data.get("probe_strides", 200), "study.probe_strides", 1, 100000),
    )


def study_mapping(study: Study) -> dict:
    """The ``study`` section a problem file would hold for ``study``: a field left at its
    default is left out, as a file would leave it (an atlas's ``max_radius`` then follows
    its ``radius``), and the grid's axes stay :class:`Axis` objects (:func:`_axes` checks
    their values).

    Parameters
    ----------
    study : Study
        A study object, possibly built in Python with any values.

    Raises
    ------
    StudyError
        If its ``kind`` is not its class's.
    """
    kind = type(study).kind
    if study.kind != kind:
        raise StudyError("study.kind", f"a {type(study).__name__} study has kind {kind}, got {excerpt(study.kind)}")
    data: dict = {"kind": kind}
    for entry in dataclasses.fields(study):
        value = getattr(study, entry.name)
        at_default = type(value) is type(entry.default) and value == entry.default
        if entry.name != "kind" and not at_default:
            key = _FILE_KEYS.get(entry.name, entry.name)
            data[key] = _file_value(value, f"study.{key}")
    return data


#: The file's key of a study field that is named otherwise in the dataclass.
_FILE_KEYS = {"axes": "vary"}


def _file_value(value, key: str):
    """A field's value as a file writes it: pairs as a mapping, a sequence as a list (a
    grid's axes and an (ydot, z) point as the reader wants them); others as they are."""
    if isinstance(value, Mapping):
        return dict(value)
    if not isinstance(value, (tuple, list)):
        return value
    if key in ("study.stable_at", "study.unstable_at") and len(value) == 2:
        return {"ydot": value[0], "z": value[1]}
    if value and all(isinstance(v, (tuple, list)) and len(v) == 2 and isinstance(v[0], str) for v in value):
        names = [v[0] for v in value]
        if len(set(names)) < len(names):
            raise StudyError(key, f"names a quantity more than once: {excerpt(names)}")
        return dict(value)
    return value if key in ("study.vary", "study.grid") else list(value)


def _atlas(data, axes: tuple[Axis, ...], kind: type[Atlas] = Atlas) -> Atlas:
    """An atlas (or a families study, ``kind``) of ``axes`` from ``data``, each key at
    the kind's default where ``data`` leaves it out."""
    default = {entry.name: entry.default for entry in dataclasses.fields(kind)}
    radius = _size(data.get("radius", 0.3), "study.radius", 1e-3, 10.0)
    max_radius = _size(data.get("max_radius", max(1.5, radius)), "study.max_radius", radius, 10.0)
    # A families study left without a plot chooses one at the run, from what the problem leaves free.
    plot = _plot(data["plot"]) if "plot" in data else kind.plot
    return kind(
        axes,
        seeds=_integer(data.get("seeds", default["seeds"]), "study.seeds", 1, 10000),
        seed=_integer(data.get("seed", 0), "study.seed", 0, 2**31 - 1),
        radius=radius,
        max_radius=max_radius,
        max_charts=_integer(data.get("max_charts", default["max_charts"]), "study.max_charts", 1, 100000),
        max_spectral_radius=(_size(data["max_spectral_radius"], "study.max_spectral_radius", 1.0, 1e6)
                             if "max_spectral_radius" in data else None),
        plot=plot,
        polish=_integer(data.get("polish", default["polish"]), "study.polish", 0, 100),
        iterations=_integer(data.get("iterations", default["iterations"]), "study.iterations", 1, 10000),
        compass_trials=_integer(data.get("compass_trials", default["compass_trials"]), "study.compass_trials", 0,
                                100000),
    )


def _plot(plot) -> tuple[str, ...]:
    """An atlas figure's two different design quantities."""
    if (not isinstance(plot, (list, tuple)) or len(plot) != 2 or not all(isinstance(n, str) for n in plot)
            or len(set(plot)) != 2):
        raise StudyError("study.plot", f"expected two different quantities, got {excerpt(plot)}")
    for name in plot:
        if name not in ANY_DESIGN:
            raise StudyError("study.plot", f"unknown quantity {clip(name)!r} (expected two of {', '.join(ANY_DESIGN)})")
    return tuple(plot)


def _size(value, key, lo: float, hi: float) -> float:
    value = number(value, key)
    if not lo <= value <= hi:
        raise StudyError(key, f"expected a size in [{lo:g}, {hi:g}], got {value:g}")
    return value


def _axes(data, key, allowed) -> tuple[Axis, ...]:
    """The axes of a file's ``{name: [start, stop, step]}``, or those of a study built in
    Python (a sequence of :class:`Axis`), checked alike."""
    if isinstance(data, (tuple, list)) and data and all(isinstance(a, Axis) for a in data):
        return _given_axes(data, key, allowed)
    if not isinstance(data, dict) or not data:
        raise StudyError(key, "expected a mapping of quantity to [start, stop, step]")
    axes = []
    for name, spec in data.items():
        where = f"{key}.{clip(str(name))}"
        if isinstance(name, NonScalarKey):
            raise StudyError(where, f"a key must be a plain name, not a {name.kind}")
        if name not in allowed:
            raise StudyError(where, f"unknown quantity (expected one of {', '.join(allowed)})")
        if not isinstance(spec, (list, tuple)) or len(spec) != 3:
            raise StudyError(where, f"expected [start, stop, step], got {excerpt(spec)}")
        start, stop, step = (number(v, where) for v in spec)
        if step <= 0 or stop < start:
            raise StudyError(where, "expected start <= stop and a positive step")
        ratio = (stop - start) / step
        if not ratio < MAX_AXIS_VALUES:  # also catches an infinite ratio from a tiny step
            raise StudyError(where, f"[{start:g}, {stop:g}] in steps of {step:g} is more than {MAX_AXIS_VALUES} values")
        count = math.floor(ratio + 1e-9) + 1
        values = tuple(round(start + i * step, VALUE_DECIMALS) for i in range(count))
        if len(set(values)) < len(values):  # rows are keyed by these values: each must be its own
            raise StudyError(where, f"a step of {step:g} is finer than the {10.0 ** -VALUE_DECIMALS:g} to which "
                             "swept values are rounded; take a step of at least that")
        axes.append(Axis(name, values))
    return tuple(axes)


def _given_axes(axes, key, allowed) -> tuple[Axis, ...]:
    """Axes built in Python: known, distinct quantities, each with 1 to
    :data:`MAX_AXIS_VALUES` finite values that increase, and stay distinct once rounded to
    :data:`VALUE_DECIMALS` decimals (as a file's grid does)."""
    checked: list[Axis] = []
    for axis in axes:
        where = f"{key}.{clip(str(axis.name))}"
        if not isinstance(axis.name, str) or axis.name not in allowed:
            raise StudyError(where, f"unknown quantity (expected one of {', '.join(allowed)})")
        if any(a.name == axis.name for a in checked):
            raise StudyError(where, "is swept twice")
        sized = hasattr(axis.values, "__len__") and not isinstance(axis.values, (str, bytes, Mapping))
        if not sized or not 1 <= len(axis.values) <= MAX_AXIS_VALUES:
            raise StudyError(where, f"expected 1 to {MAX_AXIS_VALUES} values, got {excerpt(axis.values)}")
        values = tuple(round(number(v, where), VALUE_DECIMALS) for v in axis.values)
        if any(b <= a for a, b in zip(values, values[1:])):
            raise StudyError(where, f"expected increasing values, {10.0 ** -VALUE_DECIMALS:g} apart at least "
                             f"(swept values are rounded to that), got {excerpt(axis.values)}")
        checked.append(Axis(axis.name, values))
    return tuple(checked)


#: How an optimal study goes from each start to the most stable gait near it: the descent
#: on the fixed-point manifold (:mod:`baslip.analysis.descent`), or the stability NLP,
#: which bounds the multipliers by a Schur form inside the stride NLP
#: (:mod:`baslip.gait.monodromy`).
OPTIMAL_METHODS = ("descent", "schur_nlp")


def _method(value) -> str:
    if value not in OPTIMAL_METHODS:
        raise StudyError("study.method", f"expected one of {', '.join(OPTIMAL_METHODS)}, got {excerpt(value)}")
    return value


#: The controllers a ``controllers`` study can compare.
CONTROLLER_KINDS = ("constant", "feedback", "pivot", "horizon", "resolve")
#: The controllers that solve for their controls at every apex (``solve_samples``).
RESOLVING = ("horizon", "resolve")
#: The controllers that adapt only some controls at every apex, and those controls (the
#: hip law must have them): ``pivot`` moves the virtual pivot alone (Sharbafi et al. 2013).
ADAPTED_CONTROLS = {"pivot": ("r_vpp",)}


def _boxes(value) -> tuple[float, ...]:
    """Box sizes, as multiples of the perturbation's half-widths: 1 to 64, increasing."""
    if not isinstance(value, list) or not value or len(value) > 12:
        raise StudyError("study.boxes", f"expected a list of 1 to 12 box sizes, got {excerpt(value)}")
    sizes = tuple(number(v, "study.boxes") for v in value)
    if any(not 0 < v <= 64 for v in sizes) or list(sizes) != sorted(set(sizes)):
        raise StudyError("study.boxes", f"expected increasing sizes in (0, 64], got {excerpt(value)}")
    return sizes


def _controller_names(value) -> tuple[str, ...]:
    names = value if isinstance(value, list) else [value]
    if not names or any(n not in CONTROLLER_KINDS for n in names) or len(set(names)) != len(names):
        raise StudyError("study.controllers", f"expected some of {', '.join(CONTROLLER_KINDS)}, got {excerpt(value)}")
    return tuple(names)


def _solve_samples(value) -> tuple[tuple[str, int], ...]:
    """Starts per box of the re-solving controllers: one integer for both, or a mapping
    from ``horizon`` and ``resolve`` to their own counts (a missing one runs ``samples``)."""
    key = "study.solve_samples"
    if value is None:
        return ()
    if not isinstance(value, dict):
        return tuple((name, _integer(value, key, 1, 100000)) for name in RESOLVING)
    pairs = []
    for name, count in value.items():
        if isinstance(name, NonScalarKey) or name not in RESOLVING:
            raise StudyError(f"{key}.{clip(str(name))}",
                             f"not a re-solving controller (expected {' or '.join(RESOLVING)})")
        pairs.append((name, _integer(count, f"{key}.{name}", 1, 100000)))
    return tuple(pairs)


def _criterion(value) -> str:
    if value not in ("thesis", "tracking"):
        raise StudyError("study.criterion", f"expected thesis or tracking, got {excerpt(value)}")
    return value


def _apex_map(data, key, positive: bool, required: bool = False) -> tuple[tuple[str, float], ...]:
    """A map of apex quantity to a size (``positive``: in [:data:`MIN_SIZE`, 10]) or an
    offset (any sign, at most 10 in size); SI units, and angles may carry units."""
    apex = ("z", "theta_h", "ydot", "theta_h_dot")
    what = "a size" if positive else "an offset"
    if not isinstance(data, dict) or (required and not data):
        raise StudyError(key, f"expected a mapping of apex quantity ({', '.join(apex)}) to {what}")
    pairs = []
    for name, value in data.items():
        where = f"{key}.{clip(str(name))}"
        if isinstance(name, NonScalarKey) or name not in apex:
            raise StudyError(where, f"unknown apex quantity (expected one of {', '.join(apex)})")
        value = number(value, f"{key}.{name}")
        if not (MIN_SIZE <= value <= 10 if positive else abs(value) <= 10):
            wanted = f"a size in [{MIN_SIZE:g}, 10]" if positive else "an offset of at most 10 in size"
            raise StudyError(where, f"expected {wanted}, got {value:g}")
        pairs.append((name, value))
    return tuple(pairs)


def _pair(data, key) -> tuple[float, float]:
    if not isinstance(data, dict) or set(map(str, data)) != {"ydot", "z"} or len(data) != 2:
        raise StudyError(key, "expected {ydot: ..., z: ...}")
    return number(data["ydot"], f"{key}.ydot"), number(data["z"], f"{key}.z")


def _name(value, key) -> str:
    if not isinstance(value, str) or not re.fullmatch(r"[A-Za-z0-9_.-]{1,100}", value) or set(value) == {"."}:
        raise StudyError(key, f"expected the name of another study, got {excerpt(value)}")
    return value


def _integer(value, key, lo, hi) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise StudyError(key, f"expected an integer in [{lo}, {hi}], got {excerpt(value)}")
    return value


def _fraction(value, key) -> float:
    value = number(value, key)
    if not 0 < value <= 1:
        raise StudyError(key, f"expected a relative tolerance in (0, 1], got {value:g}")
    return value
