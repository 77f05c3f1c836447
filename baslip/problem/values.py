"""Values in a problem file: mappings with known keys, finite numbers, angles and rates
with their units, and the physical range of each quantity.

Every number a problem file holds, in any section, is read by :func:`number`, so that
``-90 deg``, ``'1e-8'`` (which YAML 1.1 leaves a string) and the errors for anything
else are the same everywhere.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from baslip.errors import ProblemError
from baslip.model.dynamics import Params
from baslip.model.quantities import PARAM_RANGES, THESIS_BODY, physical_range, value_text
from baslip.model.ranges import parameter_fault
from baslip.problem.text import MalformedNumber, NonScalarKey, clip, excerpt

#: Quantities that may be given in ``deg`` or ``rad``, and rates in ``deg/s`` or ``rad/s``.
ANGLES = ("theta_h", "theta2_des", "theta_td")
RATES = ("theta_h_dot", "theta2_dot_des")


def number(value: Any, key: str) -> float:
    """A finite float; angles and rates may carry 'deg', 'rad', 'deg/s' or 'rad/s'."""
    quantity = key.rsplit(".", 1)[-1]
    if isinstance(value, MalformedNumber):
        raise ProblemError(key, f"expected a number, got {value}, whose text is no such number")
    if isinstance(value, str):
        value = _plain_or_with_unit(value, key, quantity)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProblemError(key, f"expected a number, got {type(value).__name__} {excerpt(value)}")
    try:
        value = float(value)
    except OverflowError:
        raise ProblemError(key, "number too large") from None
    if not math.isfinite(value):
        raise ProblemError(key, f"expected a finite number, got {value}")
    return value


def _plain_or_with_unit(text: str, key: str, quantity: str) -> float:
    """A number YAML left as a string: '1e-8' (YAML 1.1 wants '1.0e-8') or '-90 deg'."""
    if re.fullmatch(r"\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*", text):
        return float(text)
    return _with_unit(text, key, quantity)


def _with_unit(text: str, key: str, quantity: str) -> float:
    match = re.fullmatch(r"\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*([a-z/]+)\s*", text)
    units = {"deg": math.pi / 180, "rad": 1.0} if quantity in ANGLES else {}
    if quantity in RATES:
        units = {"deg/s": math.pi / 180, "rad/s": 1.0}
    if not match or match.group(2) not in units:
        accepted = f" or a string with unit {' / '.join(units)}" if units else ""
        raise ProblemError(key, f"expected a number{accepted}, got {excerpt(text)}")
    try:
        value = float(match.group(1)) * units[match.group(2)]
    except ValueError:
        raise ProblemError(key, f"expected a number, got {excerpt(text)}") from None
    if not math.isfinite(value):
        raise ProblemError(key, f"expected a finite number, got {excerpt(text)}")
    return value


def mapping(value: Any, key: str, allowed: tuple[str, ...]) -> dict[str, Any]:
    """``value`` as a dict, if it is a mapping (a dict, or a read-only one a problem holds)
    whose keys are all in ``allowed``; ``key`` names it."""
    where = key or "the problem file"
    if not isinstance(value, Mapping):
        raise ProblemError(key, f"expected a mapping for {where}, got {type(value).__name__}")
    for name in value:
        dotted = f"{key}.{clip(str(name))}" if key else clip(str(name))
        if isinstance(name, NonScalarKey):
            raise ProblemError(dotted, f"a key must be a plain name, not a {name.kind}")
        if name not in allowed:
            raise ProblemError(dotted, f"unknown key (expected one of {', '.join(allowed)})")
    return dict(value)


def physical(name: str, value: float, key: str, params: Params = THESIS_BODY) -> float:
    """``value`` if it lies in the documented physical range of ``name``, else an error.

    Parameters
    ----------
    name : str
        A design quantity, ``energy`` or a model parameter.
    value : float
        Its value, SI units and radians.
    key : str
        The problem file's key that holds it, for the message.
    params : Params
        The body: a design quantity's range is the thesis body's scaled to it
        (:func:`baslip.model.quantities.body_scale`).
    """
    if name in PARAM_RANGES:
        fault = parameter_fault(name, value)
        if fault is not None:
            raise ProblemError(key, fault)
        return value
    lo, hi = physical_range(name, params)
    if not lo <= value <= hi:
        if name in ANGLES and abs(value) > 2 * math.pi:  # looks like degrees written as radians
            raise ProblemError(key, f"{value:g} rad lies outside the physical range [{lo:g}, {hi:g}] rad (angles "
                               'are in radians; write "-90 deg" for degrees)')
        hint = ' (rates are in rad/s; write "30 deg/s" for degrees)' if name in RATES else ""
        body = "" if params == THESIS_BODY else " for this body (the thesis body's, scaled by its m, rho0 and g)"
        shown = [value_text(name, v, 6) for v in (value, lo, hi)]
        raise ProblemError(key, f"{shown[0]} lies outside the physical range [{shown[1]}, {shown[2]}]{body}{hint}")
    return value
