"""A gait's start from the body alone: a shipped gait carried to the body, or continued to it.

A problem with no guess gets its start here (:func:`start_from_body`):

1. **Scaling.** The shipped gaits (:mod:`baslip.gait.knowngaits`) under the problem's
   hip law and posture are ranked by how far their normalised body and fixed values lie
   from the problem's. A gait of a body with the same groups, at the same normalised fixed
   values, carries over exactly (:func:`baslip.model.similarity.carried`).
2. **Homotopy.** Otherwise the gait is continued along the straight path, in the
   dimensionless groups and the normalised fixed values, from the shipped gait to the
   problem, at the normalised body: each step a fixed-point solve warm-started from the
   last, verified by the independent re-simulation, a failed step halved (down to
   :data:`SMALLEST_STEP`); where the steps break (at a fold of the path, where s turns
   back), the last verified gait is followed by pseudo-arclength continuation in s
   (:mod:`baslip.gait.homotopy`), which turns the fold and goes on to the problem if the
   branch comes back; otherwise the next shipped gait is tried.
3. **Seeds.** Where every path breaks, the atlas's sampling at the problem's own cell:
   up to :data:`SEEDS` solves from the nearest shipped gait carried to the body (not to its
   groups or cell), first with its own gains, then with the law's gains drawn over their
   bounds (:func:`~baslip.gait.draws.random_start`, from :data:`SEED`) and held, each
   verified; the first that converges is the start.

What comes back is the start at the problem's own body; the problem's solve then polishes
and verifies it there, with the problem's bounds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from baslip.diagnostics import logger
from baslip.gait.draws import random_start
from baslip.gait.fixedpoint import FixedPointSolver
from baslip.gait.homotopy import StraightPath, follow_path
from baslip.gait.knowngaits import KnownGait, known_gaits
from baslip.gait.shooting import FixedPointSpec
from baslip.model.quantities import NOMINAL, POSTURE_BOUNDS, design_values, posture_of
from baslip.model.similarity import body_with, carried, groups, normalised_body
from baslip.status import Status

_log = logger(__name__)

#: Smallest step along a homotopy path (as a share of the whole path) before it is given up.
SMALLEST_STEP = 1 / 64
#: Shipped gaits tried, nearest first, before the drawn seeds.
TRIED_GAITS = 2
#: Seeds tried at the cell where every path breaks (the first with the nearest gait's own
#: gains, the rest with gains drawn), and the seed of their draws.
SEEDS = 6
SEED = 58


@dataclass(frozen=True)
class FoundStart:
    """A start found from the body alone, or why there is none.

    Attributes
    ----------
    guess : Mapping of str to float or None
        Every design quantity not fixed, at the problem's body (SI units, radians); None
        if no path reached the problem.
    origin : str
        How it was found (the shipped gait, scaled or continued in how many steps), or
        why none was.
    steps : int
        Fixed-point solves made along the paths.
    """

    guess: Mapping[str, float] | None
    origin: str
    steps: int = 0


def start_from_body(spec: FixedPointSpec, solver: FixedPointSolver, posture: str = "any") -> FoundStart:
    """A start for ``spec`` (one stride, no guess needed) from the shipped gaits.

    Parameters
    ----------
    spec : FixedPointSpec
        The problem: its body, hip law and fixed values (its guess is not read).
    solver : FixedPointSolver
        Solves the steps of a path; built for ``spec.law``.
    posture : str
        ``upright``, ``hanging`` or ``any``: the trunk at the apex.

    Returns
    -------
    FoundStart
    """
    candidates = ranked_gaits(spec, posture)
    failures, steps = [], 0
    if not candidates:
        failures.append(f"baslip ships no {posture} gait under the {spec.law.name} law to start from")
    for gait in candidates[:TRIED_GAITS]:
        found = _continued(gait, spec, solver)
        steps += found.steps
        if found.guess is not None:
            return replace(found, steps=steps)
        failures.append(found.origin)
    seeded = _seeded(spec, solver, candidates[0] if candidates else None)
    if seeded.guess is not None:
        return replace(seeded, origin=f"{'; '.join(failures)}; {seeded.origin}", steps=steps + seeded.steps)
    return FoundStart(None, "; ".join([*failures, seeded.origin]), steps + seeded.steps)


def _seeded(spec: FixedPointSpec, solver: FixedPointSolver, nearest: KnownGait | None) -> FoundStart:
    """The first solve at ``spec``'s cell that converges (verified), from the ``nearest``
    shipped gait carried to the body (not to its groups or cell: a start, not an answer;
    else the default guess): first as it is, then with the gains drawn and held, up to
    :data:`SEEDS` seeds in all."""
    guess = {} if nearest is None else {
        n: v for n, v in carried(nearest.values, body_with(nearest.groups), spec.params).items() if n not in spec.fixed}
    rng = np.random.default_rng(SEED)
    drawn = not all(name in spec.fixed for name in spec.law.drawn)
    for number in range(1, (SEEDS if drawn else 1) + 1):  # the posture's bounds are the spec's own
        held = random_start(spec, rng) if number > 1 else {}
        how = "its gains drawn over their bounds" if held else "the nearest shipped gait carried to the body"
        seed = replace(spec, fixed={**spec.fixed, **held}, guess={n: v for n, v in guess.items() if n not in held})
        result = solver.solve(seed, name="start from a seed")
        if result.status == Status.CONVERGED:
            values = design_values(result.X, result.u, spec.law)
            _log.info(f"start: seed {number} at this cell ({how})")
            return FoundStart({n: v for n, v in values.items() if n not in spec.fixed},
                              f"from seed {number} at this cell ({how})", number)
    return FoundStart(None, f"none of {number} seeds converged at this cell", number)


def started_from_body(spec: FixedPointSpec, solver: FixedPointSolver, posture: str = "any") -> FixedPointSpec:
    """``spec`` with the guess found from the body alone (:func:`start_from_body`); where
    none is found, ``spec`` as it is (its default guess), with a note saying why."""
    found = start_from_body(spec, solver, posture)
    if found.guess is None:
        _log.warning(f"note: no start from the body alone ({found.origin}); starting from the default guess")
        return spec
    return replace(spec, guess=dict(found.guess))


def ranked_gaits(spec: FixedPointSpec, posture: str = "any") -> list[KnownGait]:
    """The shipped gaits under ``spec``'s law (and ``posture``, unless ``any``), nearest
    to ``spec`` first (:func:`path_length`)."""
    law_gaits = [g for g in known_gaits() if g.law == spec.law.name and posture in ("any", g.posture)]
    return sorted(law_gaits, key=lambda g: path_length(g, spec))


def path_length(gait: KnownGait, spec: FixedPointSpec) -> float:
    """How far ``gait`` lies from ``spec``: its groups' distance plus its fixed values'
    distances (at the normalised body, in units of their nominal scales)."""
    target = _fixed_at(spec, normalised_body(spec.params))
    return groups(spec.params).distance(gait.groups) + sum(
        abs(gait.values[n] - v) / NOMINAL[n] for n, v in target.items())


def _fixed_at(spec: FixedPointSpec, body) -> dict[str, float]:
    """The design quantities ``spec`` fixes, carried to ``body``."""
    return carried({n: v for n, v in spec.fixed.items() if n in spec.design}, spec.params, body)


def _continued(gait: KnownGait, spec: FixedPointSpec, solver: FixedPointSolver) -> FoundStart:
    """Continue ``gait`` along the straight path to ``spec`` at the normalised body: natural
    steps, and where they break, pseudo-arclength through the folds
    (:func:`~baslip.gait.homotopy.follow_path`)."""
    end_body = normalised_body(spec.params)
    end_fixed = _fixed_at(spec, end_body)
    path = StraightPath(gait.groups, groups(spec.params), {n: gait.values[n] for n in end_fixed}, end_fixed)
    values, s, step, steps = dict(gait.values), 0.0, 1.0, 0
    while s < 1.0:
        step = min(step, 1.0 - s)
        point = _solved(path, s + step, values, spec, solver)
        steps += 1
        if point is not None:
            values, s, step = point, s + step, 2 * step
            if s < 1.0:
                _log.info(f"start: the shipped gait {gait.name!r} continued {s:.0%} of the way to this body")
            continue
        step /= 2
        if step < SMALLEST_STEP:
            return _followed(gait, path, values, s, spec, solver, steps)
    return _arrived(gait, spec, values, steps, "carried over exactly" if steps == 1 and path.is_exact()
                    else f"continued in {steps} solve{'s' * (steps > 1)}")


def _followed(gait: KnownGait, path: StraightPath, values: dict[str, float], s: float, spec: FixedPointSpec,
              solver: FixedPointSolver, steps: int) -> FoundStart:
    """Where natural steps broke at ``s``: the path followed by pseudo-arclength from the
    last verified gait ``values``, turning its folds."""
    bounds = {"theta_h": POSTURE_BOUNDS[posture_of(values["theta_h"])]}
    followed = follow_path(path, spec.law, values, s, solver.residual_map, bounds)
    if followed.values is None:
        return FoundStart(None, f"the path from the shipped gait {gait.name!r} broke at {s:.0%} of the way, and "
                          f"pseudo-arclength from there did not reach this body: {followed.why}", steps)
    fold = ", turning a fold" if followed.turned else ""
    return _arrived(gait, spec, followed.values, steps, f"continued in {steps} solves, then by pseudo-arclength from "
                    f"{s:.0%} of the way in {followed.points} points{fold}")


def _arrived(gait: KnownGait, spec: FixedPointSpec, values: Mapping[str, float], steps: int, how: str) -> FoundStart:
    """The start at the problem's body from the gait ``values`` at the path's end."""
    guess = carried({n: v for n, v in values.items() if n not in spec.fixed}, normalised_body(spec.params), spec.params)
    _log.info(f"start: the shipped gait {gait.name!r}, {how}")
    return FoundStart(guess, f"from the shipped gait {gait.name!r}, {how}", steps)


def _solved(path: StraightPath, s: float, values: Mapping[str, float], spec: FixedPointSpec,
            solver: FixedPointSolver) -> dict[str, float] | None:
    """The verified gait at ``s`` along ``path``, from ``values`` (None if none is found)."""
    groups_s, fixed = path.at(s)
    posture = posture_of(values["theta_h"])
    step_spec = FixedPointSpec(params=body_with(groups_s), fixed=fixed,
                               guess={n: v for n, v in values.items() if n not in fixed},
                               bounds={"theta_h": POSTURE_BOUNDS[posture]}, objective="nearest_guess", law=spec.law)
    result = solver.solve(step_spec, name="start from the body")
    if result.status != Status.CONVERGED:
        return None
    return design_values(result.X, result.u, spec.law)
