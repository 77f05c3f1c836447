"""The ``continuation:`` section: a branch in one parameter, and curves in two.

Checked whole when the problem is read: the keys and ranges, that the branch starts inside
its range, and that the problem defines a one-dimensional branch (as many free quantities
as equations, or more with the ``nearest_guess`` objective, which then picks the family).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from baslip.errors import ProblemError
from baslip.model.dynamics import APEX, PARAMS, Params
from baslip.model.hiplaw import PD, HipLaw
from baslip.model.quantities import ANY_DESIGN, design_names, implied_periodicity, quantity_text, value_text
from baslip.problem.text import excerpt
from baslip.problem.values import mapping, physical
from baslip.problem.values import number as _number

#: The largest first continuation step (scaled units).
MAX_STEP = 10.0


class BranchError(ProblemError):
    """The problem does not define a one-dimensional branch; ``key`` names the entry."""


@dataclass(frozen=True)
class ContinuationSpec:
    """Trace the branch of fixed points as ``parameter`` varies over [lo, hi].

    parameter: a fixed quantity (or energy) or a model parameter; step: first arclength
    step (scaled units); max_points: limit on the points; direction: +1 or -1, the way
    lambda first moves; plot: apex quantity on the diagram's vertical axis; switch:
    ``period_doubling`` to also trace, from each period doubling found on the first
    branch, the branch of orbits of twice the period.
    """

    parameter: str
    lo: float
    hi: float
    step: float = 0.05
    max_points: int = 300
    direction: int | str = 1
    plot: str = "z"
    switch: str | None = None  # "period_doubling": also trace the doubled-period branches
    second: str | None = None  # with a second parameter, bifurcation curves are followed
    second_lo: float = -math.inf
    second_hi: float = math.inf
    follow: tuple[str, ...] = ()  # curve types, each from a special point of the branch
    starts: str = "first"  # "first": one curve per type; "all": one from each such point


#: Branch switches a continuation can make at its special points.
SWITCHES = ("period_doubling",)
#: Bifurcation curves a continuation can follow in two parameters.
FOLLOWS = ("fold", "period_doubling", "neimark_sacker")
CONTINUATION_KEYS = ("parameter", "range", "step", "max_points", "direction", "plot", "switch",
                     "second", "second_range", "follow", "starts")


def parse_continuation(value: Any) -> ContinuationSpec:
    """Validate a ``continuation`` mapping, or a :class:`ContinuationSpec` built in Python
    (checked as its mapping form, :func:`continuation_mapping`, would be)."""
    if isinstance(value, ContinuationSpec):
        value = continuation_mapping(value)
    raw = mapping(value, "continuation", CONTINUATION_KEYS)
    parameter = _continued(raw.get("parameter"), "continuation.parameter")
    lo, hi = _continuation_range(raw.get("range"), parameter, "continuation.range")
    step = _number(raw.get("step", 0.05), "continuation.step")
    if not 0 < step <= MAX_STEP:
        raise ProblemError("continuation.step", f"expected a step in (0, {MAX_STEP:g}] (scaled units), got {step:g}")
    max_points = raw.get("max_points", 300)
    if isinstance(max_points, bool) or not isinstance(max_points, int) or not 2 <= max_points <= 100000:
        raise ProblemError("continuation.max_points", f"expected an integer in [2, 100000], got {excerpt(max_points)}")
    direction = raw.get("direction", 1)
    if isinstance(direction, bool) or direction not in (1, -1, "both"):
        raise ProblemError("continuation.direction", f"expected 1, -1 or both, got {excerpt(direction)}")
    plot = raw.get("plot", "z")
    if plot not in ANY_DESIGN:
        raise ProblemError("continuation.plot", f"expected a design quantity (one of {', '.join(ANY_DESIGN)}), "
                           f"got {excerpt(plot)}")
    switch = raw.get("switch")
    if switch is not None and switch not in SWITCHES:
        raise ProblemError("continuation.switch", f"expected one of {', '.join(SWITCHES)}, got {excerpt(switch)}")
    curves = _curves(raw, parameter)
    if curves and switch is not None:
        raise ProblemError("continuation.switch", "a continuation either switches branches or follows curves, not both")
    return ContinuationSpec(parameter, lo, hi, step, max_points, direction, plot, switch, **curves)


def continuation_mapping(spec: ContinuationSpec) -> dict[str, Any]:
    """The ``continuation`` section a problem file would hold for ``spec``: its ranges as
    ``[lo, hi]``, and a field left at its default left out, as a file would leave it (the
    curve keys among them, so that a spec with only some of them is refused as a file
    with only some would be).

    Parameters
    ----------
    spec : ContinuationSpec
        A continuation, possibly built in Python with any values.
    """
    data: dict[str, Any] = {"parameter": spec.parameter, "range": [spec.lo, spec.hi]}
    for name in ("step", "max_points", "direction", "plot", "switch", "second", "follow", "starts"):
        value, default = getattr(spec, name), _DEFAULTS[name]
        if not (type(value) is type(default) and value == default):
            data[name] = list(value) if isinstance(value, tuple) else value
    if (spec.second_lo, spec.second_hi) != (_DEFAULTS["second_lo"], _DEFAULTS["second_hi"]):
        data["second_range"] = [spec.second_lo, spec.second_hi]
    return data


#: The default of each field of a continuation.
_DEFAULTS = {f.name: f.default for f in fields(ContinuationSpec)}


def _continued(name: Any, key: str) -> str:
    continued = ANY_DESIGN + ("energy",) + PARAMS.names
    if name not in continued:
        raise ProblemError(key, f"expected a quantity or a model parameter (one of {', '.join(continued)}), "
                           f"got {excerpt(name)}")
    return name


def _continuation_range(bounds: Any, name: str, key: str) -> tuple[float, float]:
    if not isinstance(bounds, (list, tuple)) or len(bounds) != 2:
        raise ProblemError(key, f"expected [lo, hi], got {excerpt(bounds)}")
    where = f"{key}.{name}"
    # A design quantity's range depends on the body: check_continuation checks it.
    lo, hi = (_number(b, where) for b in bounds)
    if name in PARAMS.names:
        lo, hi = (physical(name, end, where) for end in (lo, hi))
    if lo >= hi:
        raise ProblemError(key, f"expected lo < hi, got [{lo:g}, {hi:g}]")
    return lo, hi


def _curves(raw: dict, parameter: str) -> dict:
    """The two-parameter keys (second, second_range, follow, starts): all or none."""
    present = [k for k in ("second", "second_range", "follow", "starts") if k in raw]
    if not present:
        return {}
    for key in ("second", "second_range", "follow"):
        if key not in raw:
            raise ProblemError(f"continuation.{key}", f"is needed with {', '.join(present)} (a curve in two parameters)")
    second = _continued(raw["second"], "continuation.second")
    if second == parameter:
        raise ProblemError("continuation.second", f"must differ from the first parameter ({parameter})")
    second_lo, second_hi = _continuation_range(raw["second_range"], second, "continuation.second_range")
    follow = raw["follow"] if isinstance(raw["follow"], list) else [raw["follow"]]
    if not follow or any(f not in FOLLOWS for f in follow) or len(set(follow)) != len(follow):
        raise ProblemError("continuation.follow", f"expected one or more of {', '.join(FOLLOWS)}, got {excerpt(raw['follow'])}")
    starts = raw.get("starts", "first")
    if starts not in ("first", "all"):
        raise ProblemError("continuation.starts", f"expected first or all, got {excerpt(starts)}")
    return {"second": second, "second_lo": second_lo, "second_hi": second_hi, "follow": tuple(follow), "starts": starts}


def check_continuation(spec: ContinuationSpec, fix: Mapping[str, float], params: Params, objective: str,
                       law: HipLaw = PD) -> None:
    """A branch starts at the problem's own value of its parameter, inside its range, and
    the problem defines a one-dimensional branch in each parameter."""
    ranges = [(spec.parameter, spec.lo, spec.hi, "continuation.range")]
    if spec.second is not None:
        ranges.append((spec.second, spec.second_lo, spec.second_hi, "continuation.second_range"))
    for name, lo, hi, key in ranges:
        if name not in PARAMS.names:
            for end in (lo, hi):
                physical(name, end, f"{key}.{name}", params)
        if name in PARAMS.names:
            start = getattr(params, name)
        elif name in fix:
            start = fix[name]
        else:
            continue  # not fixed: refused below, with its own message
        if not lo <= start <= hi:
            raise ProblemError(
                key,
                f"the branch starts at {quantity_text(name, start, 6)}, outside [{value_text(name, lo, 6)}, "
                f"{value_text(name, hi, 6)}]; widen the range or change the start",
            )
    check_branch(fix, params, objective, spec.parameter, law=law)
    if spec.second is not None:
        check_branch(fix, params, objective, spec.second, "continuation.second", law)


def check_branch(fix: Mapping[str, float], params: Params, objective: str, parameter: str,
                 key: str = "continuation.parameter", law: HipLaw = PD) -> None:
    """Raise :class:`BranchError` unless fixing ``fix`` (under ``params``, ``objective`` and
    hip law ``law``) leaves a one-dimensional branch in ``parameter`` (named by ``key``)."""
    check_parameter(fix, parameter, key, law)
    free, equations = branch_shape(fix, params, law)
    if len(free) < equations or (len(free) > equations and objective != "nearest_guess"):
        raise BranchError(
            "fix",
            f"a branch needs as many free quantities as equations (or more, with objective nearest_guess): "
            f"{len(free)} free ({', '.join(free)}) but {equations} equations; fix or free quantities to match",
        )


def check_parameter(fix: Mapping[str, float], parameter: str, key: str, law: HipLaw = PD) -> None:
    """Raise :class:`BranchError` unless ``parameter`` can be varied from its fixed value."""
    design = design_names(law)
    if parameter not in design + ("energy",) + PARAMS.names:
        raise BranchError(key, f"{parameter!r} cannot be varied under hip_law {law.name} (it varies one of "
                          f"{', '.join(design + ('energy',) + PARAMS.names)})")
    if parameter in design + ("energy",) and parameter not in fix:
        raise BranchError(key, f"{parameter} must be fixed (at its starting value)")


def branch_shape(fix: Mapping[str, float], params: Params, law: HipLaw = PD) -> tuple[list[str], int]:
    """The free design quantities under ``law``, and the number of fixed-point equations
    (the apex rows that structure does not already imply, plus one for a fixed energy)."""
    implied = implied_periodicity(fix, params, law)
    free = [n for n in design_names(law) if n not in fix]
    return free, len([n for n in APEX.names if n not in implied]) + ("energy" in fix)
