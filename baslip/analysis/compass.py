"""Compass search: a derivative-free descent by trial moves along a fixed set of directions.

It is what the stability descent (:mod:`baslip.analysis.descent`) falls back on where the
spectral radius has a kink that a gradient cannot cross: where two multipliers of equal
modulus meet, the radius rises like a square root on one side, and its valley floor is the
curve where they coalesce. The search knows nothing of gaits: a point is whatever the
caller's ``move`` accepts and returns.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class CompassSettings:
    """Steps in the caller's scaled units, and the trial budget.

    A step that lowers the value doubles the next (up to ``largest_step``); a sweep of all
    directions in which none does halves it: along a long, flat valley a fixed step would
    spend the budget creeping.
    The search has converged when the step falls below ``last_step``.
    """

    first_step: float = 0.05
    largest_step: float = 0.4
    last_step: float = 1e-6
    trials: int = 600


@dataclass(frozen=True)
class CompassResult:
    """Where a compass search went.

    Attributes
    ----------
    accepted : tuple
        The records (from ``move``) of the accepted points, in order; the last is the end.
    value : float
        The value at the end (the start's if nothing was accepted).
    trials : int
        Trials counted by ``move`` (those it could place).
    converged : bool
        True if the step fell below ``last_step``; False if the trial budget ran out first.
    """

    accepted: tuple
    value: float
    trials: int
    converged: bool


#: ``move(point, displacement)``: the trial at ``point`` displaced by ``displacement``
#: (scaled units) as (value, new point, record); None if it cannot be placed (not counted
#: as a trial). A trial that fails after it was placed returns an infinite value.
Move = Callable[[Any, np.ndarray], "tuple[float, Any, Any] | None"]


def compass_directions(n: int) -> list[np.ndarray]:
    """The search's directions in n coordinates: each axis both ways, then each pair of
    axes summed and differenced, both ways (2 n^2 in all). The diagonals matter at a kink
    whose valley runs obliquely to the axes, where no axis step descends.

    Parameters
    ----------
    n : int
        Number of coordinates (n >= 1).

    Returns
    -------
    list of numpy.ndarray
        The directions, axes first.
    """
    axes = np.eye(n)
    directions = [sign * axes[k] for k in range(n) for sign in (1.0, -1.0)]
    for i in range(n):
        for j in range(i + 1, n):
            for diagonal in (axes[i] + axes[j], axes[i] - axes[j]):
                directions += [diagonal, -diagonal]
    return directions


def compass_search(move: Move, point, value: float, n: int, settings: CompassSettings = CompassSettings()
                   ) -> CompassResult:
    """Minimise by compass search from ``point``, whose value is ``value``.

    Each round tries the directions of :func:`compass_directions` in turn, the one that
    last succeeded first, and takes the first that lowers the value.

    Parameters
    ----------
    move : Move
        Places a trial (see :data:`Move`).
    point
        The start, as ``move`` understands it.
    value : float
        The value at the start.
    n : int
        Number of coordinates ``move`` displaces.
    settings : CompassSettings
        Steps and budget.

    Returns
    -------
    CompassResult
    """
    accepted: list = []
    trials, step = 0, settings.first_step
    directions = compass_directions(n)
    while step >= settings.last_step:
        if trials >= settings.trials:
            return CompassResult(tuple(accepted), value, trials, False)
        taken, placed = _first_descent(move, point, value, directions, step)
        trials += placed
        if taken is None:
            step /= 2
            continue
        index, (value, point, record) = taken
        accepted.append(record)
        directions.insert(0, directions.pop(index))
        step = min(2 * step, settings.largest_step)
    return CompassResult(tuple(accepted), value, trials, True)


def _first_descent(move: Move, point, value: float, directions: list[np.ndarray], step: float):
    """((index, move's answer), trials) of the first direction whose trial by ``step``
    lowers ``value``; (None, trials) if none does."""
    placed = 0
    for index, direction in enumerate(directions):
        trial = move(point, step * direction)
        if trial is None:
            continue
        placed += 1
        if trial[0] < value:
            return (index, trial), placed
    return None, placed
