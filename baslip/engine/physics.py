"""The BA-SLIP's physics as the engine calls it, read from the model's description.

Every piece of a stride that the compiled engine, the adaptive event map and the shooting
NLP evaluate (the stance right-hand side under a hip law, flight in closed form, the
touchdown, bottom and liftoff guards, the touchdown and liftoff maps, the clearances a
fall is watched by) is a Function of :data:`baslip.model.catalogue.ba_slip.BA_SLIP`
built by :func:`baslip.model.symbolic.model_functions`, found by the description's own
names (its modes', its transitions' labels, its falls'). This module only re-orders the engine's arguments
(a state, the law's controls ``u`` with the touchdown angle among them, the parameters
``p``) into the description's ``theta``: it holds no physics, and what the engine computes
is what the description says, to the bit (``tests/test_committed_strides.py``).

The apex at the end of a stride is still :func:`baslip.model.dynamics.flight_to_apex`
(flight up to ``zdot = 0``, closed form), which a description does not carry.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import casadi as ca

from baslip.model import description, dynamics, hiplaw, lagrange, layout, symbolic
from baslip.model.catalogue import ba_slip
from baslip.model.catalogue.ba_slip import BA_SLIP
from baslip.model.description import Names
from baslip.model.dynamics import PARAMS
from baslip.model.hiplaw import HipLaw
from baslip.model.symbolic import ModelFunctions, fall_names, model_functions

#: The stance mode whose right-hand side and falls the engine reads; compression and
#: decompression share their Lagrangian and torque, so either serves.
STANCE_MODE = "compression"
#: The mode whose closed-form flow the engine steps flight with.
FLIGHT_MODE = "flight"
#: The description's falls that the engine watches in stance, in the order of its
#: clearances (CoM height, hip height, leg above the collapse floor [m]).
CLEARANCE_FALLS = ("CoM touches the ground", "hip touches the ground", "leg collapses")


@dataclass(frozen=True)
class Physics:
    """The description's Functions under one hip law, called with the engine's arguments.

    Each method takes a state (stance ``x`` or flight ``xf``), the law's controls ``u`` and
    the parameters ``p`` (SX, MX or numbers) and returns what the description's Function
    returns. The flows, guards and clearances are small expressions and are inlined into a
    symbolic caller's graph; each reset stays a call, of a Function of ``(x, u, p)`` that
    holds the description's operations. The engine's and the NLP's graphs are so built as
    they were before they read the description, and their arithmetic and iterates are
    what they were.

    Parameters
    ----------
    law : HipLaw
        The hip law, whose ``controls`` order ``u``.
    functions : ModelFunctions
        The BA-SLIP description's Functions under that law.
    resets : mapping of str to casadi.Function
        Each transition's reset by its label, a Function of ``(x, u, p)``
        (:meth:`of` builds them from ``functions``).
    """

    law: HipLaw
    functions: ModelFunctions
    resets: Mapping[str, ca.Function]

    @classmethod
    def of(cls, law: HipLaw) -> Physics:
        """The BA-SLIP description's physics under ``law``."""
        functions = model_functions(BA_SLIP, law.name)
        u, p = law.controls.sym("u"), PARAMS.sym("p")
        theta = _theta(law, functions, u, p)
        resets = {}
        for transition, reset in zip(BA_SLIP.stride_transitions(), functions.resets, strict=True):
            x = ca.SX.sym("x", reset.size1_in(0))
            resets[transition.label] = ca.Function(transition.label, [x, u, p], [_inline(reset, x, theta)],
                                                   ["x", "u", "p"], ["after"])
        return cls(law, functions, resets)

    def theta(self, u: Any, p: Any) -> Any:
        """The description's ``theta`` (parameters, then controls) from ``u`` and ``p``."""
        return _theta(self.law, self.functions, u, p)

    def stance_rate(self, x: Any, u: Any, p: Any) -> Any:
        """xdot of a stance state under the law's torque (the description's Lagrangian)."""
        return _inline(self.functions.rhs[STANCE_MODE], x, self.theta(u, p))

    def flight(self, xf: Any, t: Any, u: Any, p: Any) -> Any:
        """The flight state ``t`` [s] after ``xf``: the description's closed-form flow.

        On symbols it is the description's expression built on the caller's own symbols
        (MX as MX), so that its operations and their derivatives are the ones the engine
        built before; the Function of :attr:`functions` checked that it solves flight."""
        if not any(isinstance(a, (ca.SX, ca.MX)) for a in (xf, t, u, p)):
            return self.functions.flows[FLIGHT_MODE](xf, self.theta(u, p), t)
        mode = BA_SLIP.mode(FLIGHT_MODE)
        names = self.functions.theta_names
        values = dict(zip(names, ca.vertsplit(self.theta(u, p))))
        quantities = {q.name for q in BA_SLIP.parameters}
        after = mode.flow(Names(dict(zip(mode.states, ca.vertsplit(xf))), "the flight state"),  # type: ignore[misc]
                          Names({n: v for n, v in values.items() if n in quantities}, "p"),
                          Names({n: v for n, v in values.items() if n not in quantities}, "u"), t)
        return ca.vertcat(*[after[n] for n in mode.states])

    def guard(self, label: str, x: Any, u: Any, p: Any) -> Any:
        """The guard of the transition ``label`` (touchdown: foot height [m]; bottom:
        rhodot [m/s]; liftoff: rho - rho0 [m]) at the state of its source mode."""
        return _inline(self.functions.guards[self._transition(label)], x, self.theta(u, p))

    def reset(self, label: str, x: Any, u: Any, p: Any) -> Any:
        """The state after the transition ``label`` (touchdown: flight to stance; liftoff:
        stance to flight)."""
        # A call, not its operations: the maps were whole functions in the engine's graphs.
        return self.resets[label](x, u, p)

    def clearances(self, x: Any, u: Any, p: Any) -> Any:
        """(CoM height, hip height, rho above the collapse floor) [m] of a stance state; the
        runner falls when one reaches zero."""
        values = _inline(self.functions.falls[STANCE_MODE], x, self.theta(u, p))
        names = fall_names(BA_SLIP, STANCE_MODE)
        return ca.vertcat(*[values[names.index(n)] for n in CLEARANCE_FALLS])

    def _transition(self, label: str) -> int:
        return [t.label for t in BA_SLIP.stride_transitions()].index(label)


def _theta(law: HipLaw, functions: ModelFunctions, u: Any, p: Any) -> Any:
    """The description's ``theta`` from the law's controls ``u`` and the parameters ``p``."""
    by_name = {**{n: law.controls.get(u, n) for n in law.controls.names}, **{n: PARAMS.get(p, n) for n in PARAMS.names}}
    return ca.vertcat(*[by_name[n] for n in functions.theta_names])


def _inline(function: ca.Function, x: Any, theta: Any) -> Any:
    """``function(x, theta)``, its operations inlined where an argument is symbolic."""
    if isinstance(x, (ca.SX, ca.MX)) or isinstance(theta, (ca.SX, ca.MX)):
        return function.call([x, theta], True, False)[0]
    return function(x, theta)


def physics_modules() -> tuple[ModuleType, ...]:
    """The modules the engine's physics is derived from (a compiled library's key)."""
    return (layout, dynamics, hiplaw, description, lagrange, symbolic, ba_slip, sys.modules[__name__])
