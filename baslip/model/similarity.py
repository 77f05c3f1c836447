"""Bodies that are the same runner at another size: BA-SLIP's dimensionless groups.

With a length scale rho0, a time scale sqrt(rho0/g) and a mass scale m, the equations of
motion hold three dimensionless groups of the body,

* the leg's stiffness k rho0 / (m g),
* the trunk's inertia I / (m rho0^2),
* the hip's offset d / rho0,

and a gait holds the Froude number ydot^2 / (g rho0) and its other values in those units.
Two bodies with the same groups run the same gaits: a gait of one, carried value by value
with :func:`carried` (:func:`baslip.model.quantities.body_scale`), is a gait of the other
with the same multipliers. Every body is so represented by its *normalised body*: the
thesis's m, rho0 and g with its groups.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from baslip.model.dynamics import Params
from baslip.model.quantities import THESIS_BODY, body_scale


@dataclass(frozen=True)
class Groups:
    """The dimensionless groups of a body.

    Attributes
    ----------
    stiffness : float
        k rho0 / (m g).
    inertia : float
        I / (m rho0^2).
    offset : float
        d / rho0.
    """

    stiffness: float
    inertia: float
    offset: float

    def distance(self, other: Groups) -> float:
        """How far apart two bodies are: the largest factor between their stiffness and
        inertia groups, as a logarithm, and the difference of their offsets (per rest
        length); 0 for similar bodies."""
        return max(abs(math.log(self.stiffness / other.stiffness)), abs(math.log(self.inertia / other.inertia)),
                   abs(self.offset - other.offset))

    def interpolated(self, other: Groups, s: float) -> Groups:
        """The groups a fraction ``s`` (0 to 1) of the straight way from these to ``other``."""
        return Groups(*(a + s * (b - a) for a, b in zip(self.values(), other.values())))

    def values(self) -> tuple[float, float, float]:
        return self.stiffness, self.inertia, self.offset


def groups(params: Params) -> Groups:
    """The dimensionless groups of the body ``params``."""
    return Groups(params.k * params.rho0 / (params.m * params.g), params.I / (params.m * params.rho0**2),
                  params.d / params.rho0)


def body_with(groups_: Groups, size: Params = THESIS_BODY) -> Params:
    """The body with ``groups_`` and the mass m [kg], rest length rho0 [m] and gravity g
    [m/s^2] of ``size``."""
    m, rho0, g = size.m, size.rho0, size.g
    return Params(m=m, I=groups_.inertia * m * rho0**2, k=groups_.stiffness * m * g / rho0, rho0=rho0,
                  d=groups_.offset * rho0, g=g)


def normalised_body(params: Params) -> Params:
    """The body of the thesis's size (m, rho0, g) with the groups of ``params``."""
    return body_with(groups(params))


def carried(values: Mapping[str, float], source: Params, target: Params) -> dict[str, float]:
    """``values`` of a gait of the body ``source`` carried to the body ``target`` (exact
    for bodies of the same groups): each value scaled by its dimension (SI units, radians;
    angles unchanged).

    Parameters
    ----------
    values : Mapping of str to float
        Design quantities and ``energy`` [SI units, rad].
    source, target : Params
        The bodies the values come from and go to.
    """
    return {name: value * body_scale(name, target) / body_scale(name, source) for name, value in values.items()}


def froude(ydot: float, params: Params) -> float:
    """The Froude number ydot^2 / (g rho0) of a forward speed ``ydot`` [m/s] of ``params``'s body."""
    return ydot**2 / (params.g * params.rho0)
