"""A hybrid legged model as a description: what every described-model layer reads.

A :class:`Model` names its parameters, its modes (coordinates and a Lagrangian, or
equations of motion), the transitions between them (a guard with its direction and a
reset), the order of modes within a stride, the Poincare section and its coordinates,
its falls, and its control laws. Nothing here integrates, optimises or reads files: the
engine (:mod:`baslip.engine.hybrid`), the gait solver (:mod:`baslip.gait.modelsolver`) and
the analysis (``baslip.analysis.model*``) build everything from these fields.

Functions of a description take named symbols: ``s`` (the mode's states, ``s.z``), ``p``
(the parameters, ``p.m``) and ``u`` (the controls, ``u.theta_td``), each a
:class:`Names`, and return a CasADi expression (a guard, a Lagrangian, a fall) or a
mapping from names to expressions (forces by coordinate, a reset by target state,
equations of motion by state). All quantities are SI and angles are radians.

A guard fires when it crosses zero in its ``direction`` (+1: rising through zero, -1:
falling), having been on the other side: a guard that starts a mode at zero and moves
away to its firing side does not fire (the liftoff guard at touchdown, for one).
:func:`baslip.model.symbolic.model_functions` refuses a description that cannot be run,
naming the part.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from baslip.errors import ProblemError

#: A description's function of named symbols: ``f(s, p, u)``.
Expression = Callable[..., Any]


class ModelError(ProblemError):
    """A model description that cannot be run; ``key`` names the part (``model.modes.stance``)."""


class Names(Mapping[str, Any]):
    """Symbols (or numbers) by name, read as attributes: ``s.z`` is ``s["z"]``."""

    def __init__(self, values: Mapping[str, Any], what: str):
        self._values = dict(values)
        self._what = what

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(f"{self._what} has no {name!r}; it has {tuple(self._values)}") from None

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)


@dataclass(frozen=True)
class Quantity:
    """A parameter or control: its name, SI unit, default value and range.

    Parameters
    ----------
    name : str
        The name functions read it by (``p.k``, ``u.theta_td``).
    unit : str
        Its SI unit, e.g. ``"N/m"``, ``"rad"``, ``""`` for a pure number.
    default : float
        Its value where a problem gives none.
    low, high : float
        Its range: a problem's value outside it is refused, and a search stays inside it.
    dimension : tuple of three floats
        Its exponents of mass, length and time (k: (1, 0, -2)), by which a body of another
        size scales it; angles and pure numbers are (0, 0, 0).
    """

    name: str
    unit: str
    default: float
    low: float = -float("inf")
    high: float = float("inf")
    dimension: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Mode:
    """A continuous phase: its coordinates, and its Lagrangian or its equations of motion.

    Parameters
    ----------
    name : str
        The mode's name (``"flight"``, ``"stance"``).
    coordinates : tuple of str
        The generalized coordinates q; the state is q followed by their rates.
    rates : tuple of str, optional
        The names of the rates, in the order of ``coordinates``; ``<q>_dot`` by default.
    lagrangian : callable, optional
        ``L(s, p, u)``, kinetic minus potential energy [J]; the equations of motion are
        derived from it (:mod:`baslip.model.lagrange`).
    forces : callable, optional
        ``Q(s, p, u)``: generalized forces that are not in L (damping, thrust), by
        coordinate name; coordinates left out get none.
    dynamics : callable, optional
        ``f(s, p, u)``: each state's rate by state name, instead of a Lagrangian.
    flow : callable, optional
        ``phi(s, p, u, t)``: the state ``t`` seconds after ``s``, by state name, in closed
        form (ballistic flight, for one), for the engines that step a mode exactly. It
        must solve the mode's equations of motion, which
        :func:`~baslip.model.symbolic.model_functions` checks.
    """

    name: str
    coordinates: tuple[str, ...]
    rates: tuple[str, ...] = ()
    lagrangian: Expression | None = None
    forces: Expression | None = None
    dynamics: Expression | None = None
    flow: Expression | None = None

    @property
    def rate_names(self) -> tuple[str, ...]:
        """The rates' names: ``rates``, or ``<q>_dot`` for each coordinate."""
        return self.rates or tuple(f"{q}_dot" for q in self.coordinates)

    @property
    def states(self) -> tuple[str, ...]:
        """The mode's state: its coordinates, then their rates."""
        return (*self.coordinates, *self.rate_names)


@dataclass(frozen=True)
class Transition:
    """The event that ends mode ``source`` and starts mode ``target``.

    Parameters
    ----------
    source, target : str
        Mode names.
    guard : callable
        ``g(s, p, u)`` on the source mode's states; the transition fires when it crosses
        zero in ``direction``.
    direction : int
        +1 (rising through zero) or -1 (falling).
    reset : callable, optional
        ``R(s, p, u)``: the target mode's states by name (or a sequence in its state
        order) from the source's; None keeps the state (the two modes must share states).
    name : str
        What the event is called (``"touchdown"``).
    """

    source: str
    target: str
    guard: Expression
    direction: int
    reset: Expression | None = None
    name: str = ""

    @property
    def label(self) -> str:
        """The event's name, or ``source->target``."""
        return self.name or f"{self.source}->{self.target}"


@dataclass(frozen=True)
class Section:
    """The Poincare section a stride starts and ends on, and its coordinates.

    Parameters
    ----------
    mode : str
        The mode the section lies in: the stride's first and last.
    guard : callable
        ``g(s, p, u)``; the stride ends where it crosses zero in ``direction``.
    direction : int
        +1 or -1.
    coordinates : tuple of str
        The states that the return map maps (the apex: z, ydot).
    cyclic : tuple of str
        States dropped from the map: set to zero at the start and free at the end (y).
    pinned : mapping of str to float
        The states fixed on the section (the apex: zdot = 0). Every state of the mode is
        in exactly one of ``coordinates``, ``cyclic`` and ``pinned``.
    units : mapping of str to str
        The SI unit of each coordinate (``"rad"`` lets a problem file give degrees).
    dimensions : mapping of str to (float, float, float)
        Each coordinate's exponents of mass, length and time (``ydot``: (0, 1, -1)), by
        which a body of another size scales it; (0, 0, 0) where not given.
    """

    mode: str
    guard: Expression
    direction: int
    coordinates: tuple[str, ...]
    cyclic: tuple[str, ...] = ()
    pinned: Mapping[str, float] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    dimensions: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class Fall:
    """A way to fall: the stride fails where its condition is negative.

    Parameters
    ----------
    name : str
        What the fall is called (``"mass hit the ground"``).
    mode : str
        The mode it is checked in, at every node.
    condition : callable
        ``c(s, p, u)``, which must stay >= 0.
    """

    name: str
    mode: str
    condition: Expression


@dataclass(frozen=True)
class ControlLaw:
    """A control law: its controls, and the generalized forces it applies in each mode.

    Parameters
    ----------
    name : str
        The law's name (``"pd"``).
    controls : tuple of Quantity
        The law's own controls, besides the model's shared ones.
    forces : mapping of str to callable
        By mode name, ``Q(s, p, u)``: forces by coordinate name.
    families : int
        How many multipliers are 1 by structure at every gait of the law, besides its
        invariants': a family of time-symmetric gaits at fixed controls, as under a law
        of positions only (the BA-SLIP's VPP law: 1).
    """

    name: str
    controls: tuple[Quantity, ...] = ()
    forces: Mapping[str, Expression] = field(default_factory=dict)
    families: int = 0


@dataclass(frozen=True)
class Invariant:
    """A quantity the stride conserves under some laws (energy, under a passive law):
    each gives a multiplier that is 1 by structure.

    Parameters
    ----------
    name : str
        Its name, by which a problem may fix it (``energy``).
    value : callable
        ``v(s, p, u)`` on the section mode's states, in its SI unit.
    laws : tuple of str
        The laws it holds under; every law if empty.
    unit : str
        Its SI unit (``"J"``).
    dimension : tuple of three floats
        Its exponents of mass, length and time (energy: (1, 2, -2)).
    """

    name: str
    value: Expression
    laws: tuple[str, ...] = ()  # empty: under every law
    unit: str = ""
    dimension: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Model:
    """A hybrid legged model.

    Parameters
    ----------
    name : str
        The model's name.
    parameters : tuple of Quantity
        Physical parameters, by which functions read ``p``.
    modes : tuple of Mode
        The continuous phases.
    order : tuple of str
        Mode names in the order of one stride, the section's mode first.
    transitions : tuple of Transition
        One for each consecutive pair in ``order``.
    section : Section
        Where a stride starts and ends.
    laws : tuple of ControlLaw
        The control laws; the first is the default.
    controls : tuple of Quantity
        Controls every law shares (a touchdown angle).
    falls : tuple of Fall
        Named failures.
    invariants : tuple of Invariant
        Conserved quantities, each a structural multiplier of 1.
    description : str
        One line on what the model is.
    reference : mapping of str to float
        A known gait under the first law at the default parameters: its section
        coordinates and controls. A problem with no guess starts from it, carried to its
        own body and fixed values (:mod:`baslip.analysis.modelstart`).
    """

    name: str
    parameters: tuple[Quantity, ...]
    modes: tuple[Mode, ...]
    order: tuple[str, ...]
    transitions: tuple[Transition, ...]
    section: Section
    laws: tuple[ControlLaw, ...] = (ControlLaw("passive"),)
    controls: tuple[Quantity, ...] = ()
    falls: tuple[Fall, ...] = ()
    invariants: tuple[Invariant, ...] = ()
    description: str = ""
    reference: Mapping[str, float] = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"<Model {self.name}: modes {' -> '.join(self.order)}, laws {[law.name for law in self.laws]}, "
                f"section {self.section.coordinates}>")

    def mode(self, name: str) -> Mode:
        """The mode called ``name``.

        Parameters
        ----------
        name : str
            A mode's name.
        """
        for mode in self.modes:
            if mode.name == name:
                return mode
        raise ModelError(f"model {self.name}", f"no mode {name!r}; its modes are {[m.name for m in self.modes]}")

    def law(self, name: str | None = None) -> ControlLaw:
        """The law called ``name``.

        Parameters
        ----------
        name : str, optional
            A law's name; the model's first law if None.
        """
        if name is None:
            return self.laws[0]
        for law in self.laws:
            if law.name == name:
                return law
        raise ModelError("law", f"{name!r} is not a law of {self.name}; its laws are {[law.name for law in self.laws]}")

    def transition(self, source: str, target: str) -> Transition:
        """The transition from one mode to another.

        Parameters
        ----------
        source, target : str
            The modes' names.
        """
        for transition in self.transitions:
            if (transition.source, transition.target) == (source, target):
                return transition
        raise ModelError("model.transitions", f"no transition from {source!r} to {target!r}, "
                                              f"which the stride order {self.order} needs")

    def stride_transitions(self) -> tuple[Transition, ...]:
        """The transitions of one stride, in order."""
        return tuple(self.transition(a, b) for a, b in zip(self.order, self.order[1:]))

    def controls_of(self, law: str | None = None) -> tuple[Quantity, ...]:
        """The shared controls, then those of a law.

        Parameters
        ----------
        law : str, optional
            The law's name (the first if None).
        """
        return (*self.controls, *self.law(law).controls)

    def invariants_of(self, law: str | None = None) -> tuple[Invariant, ...]:
        """The invariants that hold under a law.

        Parameters
        ----------
        law : str, optional
            The law's name (the first if None).
        """
        name = self.law(law).name
        return tuple(i for i in self.invariants if not i.laws or name in i.laws)

    @property
    def section_mode(self) -> Mode:
        """The mode the section lies in."""
        return self.mode(self.section.mode)

    def quantities(self, law: str | None = None) -> tuple[Quantity, ...]:
        """The controls under a law, then the parameters (the section coordinates are
        states, named by :attr:`Section.coordinates`).

        Parameters
        ----------
        law : str, optional
            The law's name (the first if None).
        """
        return (*self.controls_of(law), *self.parameters)

    def _named(self, name: str, law: str | None) -> Quantity | Invariant | None:
        """The control, parameter or invariant called ``name``, or None."""
        named: list[Quantity | Invariant] = [*self.quantities(law), *self.invariants]
        return next((q for q in named if q.name == name), None)

    def dimension(self, name: str, law: str | None = None) -> tuple[float, float, float]:
        """The exponents of mass, length and time of a section coordinate, a control, a
        parameter or an invariant ((0, 0, 0) if none is given).

        Parameters
        ----------
        name : str
            The quantity's name.
        law : str, optional
            The law whose controls count (the first if None).
        """
        named = self._named(name, law)
        return named.dimension if named is not None else self.section.dimensions.get(name, (0.0, 0.0, 0.0))

    def time_scale(self, values: Mapping[str, float]) -> float:
        """A characteristic time [s] of the body ``values`` gives: the product of powers
        of the parameters whose dimension is time (sqrt(l0/g) for a SLIP), by least
        squares over their dimensions; 1 s if no parameter has a dimension.

        Parameters
        ----------
        values : mapping of str to float
            The parameters' values by name.
        """
        used = [q for q in self.parameters if any(q.dimension) and values.get(q.name, q.default) > 0]
        if not used:
            return 1.0
        matrix = np.array([q.dimension for q in used], dtype=float).T
        powers = np.linalg.lstsq(matrix, np.array([0.0, 0.0, 1.0]), rcond=None)[0]
        if not np.allclose(matrix @ powers, [0.0, 0.0, 1.0], atol=1e-9):
            return 1.0
        return float(np.exp(sum(p * np.log(values.get(q.name, q.default)) for p, q in zip(powers, used))))

    def unit(self, name: str, law: str | None = None) -> str:
        """The SI unit of a section coordinate, a control, a parameter or an invariant
        ("" if none is given).

        Parameters
        ----------
        name : str
            The quantity's name.
        law : str, optional
            The law whose controls count (the first if None).
        """
        named = self._named(name, law)
        return named.unit if named is not None else self.section.units.get(name, "")
