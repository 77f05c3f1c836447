"""What to solve for a described model: which quantities are fixed, which are free, and
where the search starts.

:class:`ModelSpec` is to a model description what
:class:`baslip.gait.shooting.FixedPointSpec` is to BA-SLIP. It is built from Python, or
from a problem file whose ``model`` names a description (:mod:`baslip.problem.model_file`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property

from baslip.errors import ArgumentError
from baslip.model.description import Model
from baslip.model.sizes import Similarity, similarity


@dataclass(frozen=True)
class ModelSpec:
    """A fixed-point problem of a described model.

    Every quantity (a section coordinate, a control, a parameter) is either fixed, with
    its value in ``fixed``, or free, with its starting value in ``guess``. Parameters and
    controls left out of both keep their defaults and are fixed. ``fixed`` may also hold
    an invariant of the law (``energy``), which adds the equation that it has that value.

    Parameters
    ----------
    model : Model
        The description.
    law : str, optional
        The control law (the model's first if None).
    fixed : mapping of str to float
        Fixed quantities, SI units and radians.
    guess : mapping of str to float
        Free quantities and where their search starts.
    bounds : mapping of str to (float, float)
        Bounds of free quantities, besides their own ranges.
    nodes : int
        Shooting intervals per mode in the NLP.
    tolerance : float
        The return map's accuracy, and the verification's (relative to max(1, |x|)).
    """

    model: Model
    law: str | None = None
    fixed: Mapping[str, float] = field(default_factory=dict)
    guess: Mapping[str, float] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    nodes: int = 20
    tolerance: float = 1e-10

    def __post_init__(self):
        names = self.names
        invariants = tuple(i.name for i in self.model.invariants_of(self.law))
        for group in ("fixed", "guess", "bounds"):
            for name in getattr(self, group):
                if name not in names and not (group == "fixed" and name in invariants):
                    raise ArgumentError(f"{group}.{name}", f"is not a quantity of model {self.model.name} "
                                                           f"(its quantities: {', '.join(names + invariants)})")
        given = [(f"{group}.{name}", name, value) for group in ("fixed", "guess")
                 for name, value in getattr(self, group).items()]
        for key, _, value in given:
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ArgumentError(key, f"must be a finite number, not {value!r}")
        for key, name, value in given:
            low, high = self.range_of(name)
            if name in names and not low <= value <= high:
                raise ArgumentError(key, f"{value:g} lies outside its range [{low:g}, {high:g}]")
        both = sorted(set(self.fixed) & set(self.guess))
        if both:
            raise ArgumentError(both[0], "is both fixed and guessed; give it in one of them")
        missing = [c for c in self.model.section.coordinates if c not in self.fixed and c not in self.guess]
        if missing:
            raise ArgumentError(missing[0], "is a section coordinate: fix it or guess it")
        if not isinstance(self.nodes, int) or self.nodes < 2:
            raise ArgumentError("nodes", f"must be an integer of at least 2, not {self.nodes!r}")
        if not 0 < self.tolerance < 1e-4:
            raise ArgumentError("tolerance", f"must lie in (0, 1e-4), not {self.tolerance!r}")

    @property
    def names(self) -> tuple[str, ...]:
        """Every quantity's name: section coordinates, controls, parameters."""
        quantities = self.model.quantities(self.law)
        return (*self.model.section.coordinates, *(q.name for q in quantities))

    @property
    def free(self) -> tuple[str, ...]:
        """The free quantities, in the order of :attr:`names`."""
        return tuple(n for n in self.names if n in self.guess)

    def values(self) -> dict[str, float]:
        """Every quantity's value: fixed, guessed, or its default (invariants left out)."""
        defaults = {q.name: q.default for q in self.model.quantities(self.law)}
        fixed = {k: float(v) for k, v in self.fixed.items() if k in self.names}
        return {**defaults, **fixed, **{k: float(v) for k, v in self.guess.items()}}

    @cached_property
    def _similarity(self) -> Similarity:
        """The factors from the model's default body to this spec's (:mod:`baslip.model.sizes`),
        found once: every control's range reads them."""
        values = self.values()
        return similarity(self.model, {q.name: values[q.name] for q in self.model.parameters})

    @property
    def fixed_invariants(self) -> dict[str, float]:
        """The invariants fixed, by name, in the order of the law's invariants."""
        return {i.name: float(self.fixed[i.name]) for i in self.model.invariants_of(self.law) if i.name in self.fixed}

    def range_of(self, name: str) -> tuple[float, float]:
        """The bounds of a quantity: its own range (a control's scaled from the model's
        default body to the spec's, :mod:`baslip.model.sizes`) within the spec's bounds.

        Parameters
        ----------
        name : str
            The quantity's name.
        """
        low, high = -math.inf, math.inf
        for quantity in self.model.quantities(self.law):
            if quantity.name == name:
                low, high = quantity.low, quantity.high
        if any(q.name == name for q in self.model.controls_of(self.law)):
            # A control's range is given at the default body; at another size it scales
            # with its dimension (a human's PD gains are hundreds of times a 1 kg runner's).
            factor = self._similarity.factor(self.model.dimension(name, self.law))
            low, high = low * factor, high * factor
        if name in self.bounds:
            lo, hi = self.bounds[name]
            low, high = max(low, lo), min(high, hi)
        return low, high
