"""The physical range of each model parameter, and the one check of a parameter's value.

Shared by :class:`baslip.model.dynamics.Params` (which checks itself when built) and the
problem reader, so that a parameter is refused with the same message however it comes in.
"""

from __future__ import annotations

import math
import numbers

#: Physical range of each model parameter: (lo, hi, whether lo itself is allowed).
#: Mass [kg], inertia [kg m^2], stiffness [N/m], rest length [m], hip offset [m], gravity [m/s^2].
PARAM_RANGES = {
    "m": (0.0, 1e4, False),
    "I": (0.0, 1e4, False),
    "k": (0.0, 1e8, False),
    "rho0": (0.0, 10.0, False),
    "d": (0.0, 10.0, True),
    "g": (0.0, 100.0, False),
}
#: SI unit of each model parameter.
PARAM_UNITS = {"m": "kg", "I": "kg m^2", "k": "N/m", "rho0": "m", "d": "m", "g": "m/s^2"}


def parameter_fault(name: str, value: object) -> str | None:
    """What is wrong with ``value`` as model parameter ``name`` (one line), or None.

    Parameters
    ----------
    name : str
        A key of :data:`PARAM_RANGES`.
    value : object
        The value, SI units (see :data:`PARAM_UNITS`).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return f"expected a finite number, got {type(value).__name__}"
    number = float(value)
    if not math.isfinite(number):
        return f"expected a finite number, got {number}"
    lo, hi, closed = PARAM_RANGES[name]
    unit = PARAM_UNITS[name]
    if number < lo or (number == lo and not closed):
        return f"must be {'zero or ' if closed else ''}positive, got {number:g} {unit}"
    if number > hi:
        return f"{number:g} {unit} exceeds the physical range (at most {hi:g} {unit})"
    return None
