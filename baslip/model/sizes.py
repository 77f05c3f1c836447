"""A described model's body at another size: the factors of mass, length and time that
bring its default parameters nearest a given body's.

Two bodies whose parameters differ by such factors, each parameter by its own dimension,
are the same model at another size: a gait of one, each value scaled by the factor of its
dimension, is a gait of the other with the same multipliers. Where no factors bring the
defaults exactly to the body, the nearest ones (least squares in the logarithms) still
give each control the size of its range there, and the distance left says how far the
body is from any similar one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from baslip.model.description import Model


@dataclass(frozen=True)
class Similarity:
    """Factors of mass, length and time from the default body to the nearest similar one,
    and how far the given parameters lie from it (the largest log-ratio left)."""

    mass: float
    length: float
    time: float
    distance: float

    def factor(self, dimension: tuple[float, float, float]) -> float:
        """The factor of a quantity of ``dimension`` (exponents of mass, length, time)."""
        a, b, c = dimension
        return self.mass**a * self.length**b * self.time**c


def similarity(model: Model, params: Mapping[str, float]) -> Similarity:
    """The similar body nearest ``params`` (every parameter's value by name).

    Parameters
    ----------
    model : Model
        The description, whose parameters' defaults and dimensions are the reference.
    params : mapping of str to float
        The body's parameters, SI units.
    """
    rows, ratios = [], []
    for quantity in model.parameters:
        if any(quantity.dimension) and quantity.default > 0 and params[quantity.name] > 0:
            rows.append(quantity.dimension)
            ratios.append(math.log(params[quantity.name] / quantity.default))
    if not rows:
        return Similarity(1.0, 1.0, 1.0, 0.0)
    logs = np.linalg.lstsq(np.array(rows, dtype=float), np.array(ratios), rcond=None)[0]
    left = np.array(ratios) - np.array(rows, dtype=float) @ logs
    mass, length, time = (float(f) for f in np.exp(logs))
    return Similarity(mass, length, time, float(np.max(np.abs(left))))
