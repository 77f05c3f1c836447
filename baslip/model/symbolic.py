"""A model description made symbolic: the CasADi functions the engine and the solvers call.

:func:`model_functions` checks a :class:`~baslip.model.description.Model` part by part and
builds, under one control law, SX Functions of a mode's state ``x`` and
``theta = (parameters, controls)``: each mode's right-hand side, each stride transition's
guard and reset, the section's guard, the falls and the invariants. A description that
cannot be run is refused with a :class:`~baslip.model.description.ModelError` naming the
part: a section coordinate that is not a state, a reset of the wrong size, a guard that
cannot fire, a Lagrangian without some rate.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from baslip.model.description import Expression, Mode, Model, ModelError, Names
from baslip.model.lagrange import accelerations, check_rates


@dataclass(frozen=True)
class ModelFunctions:
    """The symbolic pieces of a model under one law (see the module's docstring).

    ``guards[i]``, ``resets[i]`` and ``directions[i]`` belong to the i-th transition of a
    stride (``model.order[i]`` to ``model.order[i + 1]``); ``rhs`` and ``falls`` are by
    mode name; every Function takes ``(x, theta)``, but ``flows`` (the closed-form flows
    of the modes that give one, by mode name) take ``(x, theta, t)``.
    """

    model: Model
    law: str
    theta_names: tuple[str, ...]
    rhs: Mapping[str, ca.Function]
    guards: tuple[ca.Function, ...]
    resets: tuple[ca.Function, ...]
    directions: tuple[int, ...]
    section_guard: ca.Function
    falls: Mapping[str, ca.Function]
    invariants: ca.Function | None
    flows: Mapping[str, ca.Function] = field(default_factory=dict)

    @property
    def section_states(self) -> tuple[str, ...]:
        return self.model.section_mode.states

    def theta(self, values: Mapping[str, float]) -> np.ndarray:
        """The vector theta from values by name (parameters and controls)."""
        return np.array([float(values[n]) for n in self.theta_names])

    def lift(self, section_values: Any) -> Any:
        """The section mode's full state from the section coordinates (numbers, or a
        CasADi column): cyclic states at zero, pinned states at their values."""
        symbolic = isinstance(section_values, (ca.SX, ca.MX))
        if isinstance(section_values, ca.DM):
            section_values = np.array(section_values)
        entries = ca.vertsplit(section_values) if symbolic else list(np.ravel(section_values))
        section = self.model.section
        given = dict(zip(section.coordinates, entries))
        given.update({c: 0.0 for c in section.cyclic})
        given.update({k: float(v) for k, v in section.pinned.items()})
        column = [given[n] for n in self.section_states]
        return ca.vertcat(*column) if symbolic else np.array(column, dtype=float)

    def project(self, state: np.ndarray) -> np.ndarray:
        """The section coordinates of the section mode's full ``state``."""
        index = [self.section_states.index(c) for c in self.model.section.coordinates]
        return np.asarray(state, dtype=float)[index]

    @property
    def section_index(self) -> list[int]:
        return [self.section_states.index(c) for c in self.model.section.coordinates]


def _call(function: Expression, key: str, *args):
    """A description's function on symbols, with its errors named by ``key``."""
    try:
        return function(*args)
    except (AttributeError, KeyError, TypeError, ValueError, RuntimeError) as err:
        raise ModelError(key, f"{type(err).__name__}: {err}") from None


def _scalar(value, key: str) -> ca.SX:
    expr = ca.SX(value) if not isinstance(value, ca.SX) else value
    if expr.numel() != 1:
        raise ModelError(key, f"must give one value, not {expr.numel()}")
    return expr


def _column(values, names: Sequence[str], key: str, what: str) -> ca.SX:
    """A column in the order of ``names`` from a mapping by name or a sequence."""
    if isinstance(values, Mapping):
        unknown = sorted(set(values) - set(names))
        missing = [n for n in names if n not in values]
        if unknown:
            raise ModelError(key, f"names {unknown}, which are not {what} {tuple(names)}")
        if missing:
            raise ModelError(key, f"leaves out {missing} of {what} {tuple(names)}")
        return ca.vertcat(*[ca.SX(values[n]) for n in names])
    column = ca.vertcat(*values) if isinstance(values, (list, tuple)) else ca.SX(values)
    if column.numel() != len(names):
        raise ModelError(key, f"gives {column.numel()} values; {what} has {len(names)} {tuple(names)}")
    return ca.reshape(column, len(names), 1)


def _forces(mode: Mode, model: Model, law: str | None, s: Names, p: Names, u: Names, key: str) -> ca.SX:
    """The generalized forces on ``mode``'s coordinates: the mode's own plus the law's."""
    total = {q: ca.SX(0) for q in mode.coordinates}
    sources = [(mode.forces, f"{key}.forces")]
    law_forces = model.law(law).forces.get(mode.name)
    sources.append((law_forces, f"law.{model.law(law).name}.forces.{mode.name}"))
    for function, where in sources:
        if function is None:
            continue
        given = _call(function, where, s, p, u)
        if not isinstance(given, Mapping):
            raise ModelError(where, "must return forces by coordinate name (a dict)")
        for name, value in given.items():
            if name not in total:
                raise ModelError(where, f"gives a force on {name!r}, which is not a coordinate of {mode.coordinates}")
            total[name] = total[name] + _scalar(value, where)
    return ca.vertcat(*[total[q] for q in mode.coordinates])


def _rhs(mode: Mode, model: Model, law: str | None, x: ca.SX, p: Names, u: Names) -> ca.SX:
    key = f"model.modes.{mode.name}"
    if (mode.lagrangian is None) == (mode.dynamics is None):
        raise ModelError(key, "give exactly one of lagrangian and dynamics")
    if mode.rates and len(mode.rates) != len(mode.coordinates):
        raise ModelError(f"{key}.rates", f"names {len(mode.rates)} rates for {len(mode.coordinates)} coordinates")
    if len(set(mode.states)) != len(mode.states):
        raise ModelError(key, f"its states {mode.states} repeat a name")
    s = Names(dict(zip(mode.states, ca.vertsplit(x))), f"mode {mode.name}")
    if mode.dynamics is not None:
        return _column(_call(mode.dynamics, f"{key}.dynamics", s, p, u), mode.states, f"{key}.dynamics",
                       f"mode {mode.name}'s states")
    n = len(mode.coordinates)
    q, rates = x[:n], x[n:]
    lagrangian = _scalar(_call(mode.lagrangian, f"{key}.lagrangian", s, p, u), f"{key}.lagrangian")  # type: ignore[arg-type]
    check_rates(lagrangian, rates, mode.rate_names, f"{key}.lagrangian")
    forces = _forces(mode, model, law, s, p, u, key)
    return ca.vertcat(rates, accelerations(lagrangian, q, rates, forces))


def _direction(value: int, key: str) -> int:
    if value not in (1, -1):
        raise ModelError(f"{key}.direction", f"must be +1 (rising) or -1 (falling), not {value!r}")
    return value


def _check_section(model: Model) -> None:
    section = model.section
    key = "model.section"
    states = model.mode(section.mode).states
    if not model.order or model.order[0] != section.mode or model.order[-1] != section.mode:
        raise ModelError("model.order", f"must start and end in the section's mode {section.mode!r}, not {model.order}")
    for group, names in (("coordinates", section.coordinates), ("cyclic", section.cyclic),
                         ("pinned", tuple(section.pinned))):
        for name in names:
            if name not in states:
                raise ModelError(f"{key}.{group}", f"{name!r} is not a state of mode {section.mode!r} {states}")
    named = [*section.coordinates, *section.cyclic, *section.pinned]
    left = [n for n in states if n not in named]
    repeated = sorted({n for n in named if named.count(n) > 1})
    if left or repeated:
        raise ModelError(key, f"each state of {section.mode!r} must be a coordinate, cyclic or pinned once "
                              f"(left out: {left}, repeated: {repeated})")


def _guard(function: Expression, x: ca.SX, s: Names, p: Names, u: Names, key: str) -> ca.SX:
    """A guard on symbols; refused if it does not depend on the state (it could never cross)."""
    value = _scalar(_call(function, key, s, p, u), key)
    if not ca.depends_on(value, x):
        raise ModelError(key, "does not depend on the mode's state, so it never fires")
    return value


def model_functions(model: Model, law: str | None = None) -> ModelFunctions:
    """Check ``model`` and build its symbolic functions under ``law`` (the first if None).

    Raises
    ------
    ModelError
        Naming the part of the description that cannot be run.
    """
    law_name = model.law(law).name
    controls = model.controls_of(law_name)
    theta_names = tuple(q.name for q in (*model.parameters, *controls))
    if len(set(theta_names)) != len(theta_names):
        raise ModelError("model.parameters", f"parameters and controls repeat a name: {theta_names}")
    theta = ca.SX.sym("theta", len(theta_names))
    values = dict(zip(theta_names, ca.vertsplit(theta)))
    p = Names({q.name: values[q.name] for q in model.parameters}, "p (the parameters)")
    u = Names({q.name: values[q.name] for q in controls}, f"u (the controls of law {law_name!r})")
    for mode_name in model.law(law_name).forces:
        model.mode(mode_name)
    _check_section(model)

    def state(mode: Mode) -> tuple[ca.SX, Names]:
        x = ca.SX.sym("x", len(mode.states))
        return x, Names(dict(zip(mode.states, ca.vertsplit(x))), f"mode {mode.name}")

    rhs, flows = {}, {}
    for mode in model.modes:
        x, s = state(mode)
        rhs[mode.name] = ca.Function(f"{mode.name}_rhs", [x, theta], [_rhs(mode, model, law_name, x, p, u)])
        if mode.flow is not None:
            flows[mode.name] = _flow(mode, x, s, theta, p, u)
            _check_flow(mode, flows[mode.name], rhs[mode.name], model, law_name)
    guards, resets, directions = [], [], []
    for transition in model.stride_transitions():
        key = f"model.transitions.{transition.label}"
        source, target = model.mode(transition.source), model.mode(transition.target)
        x, s = state(source)
        guards.append(ca.Function(f"{transition.label}_guard", [x, theta],
                                  [_guard(transition.guard, x, s, p, u, f"{key}.guard")]))
        directions.append(_direction(transition.direction, key))
        if transition.reset is None:
            if source.states != target.states:
                raise ModelError(f"{key}.reset", f"is needed: {source.name!r} and {target.name!r} have different states")
            after = x
        else:
            after = _column(_call(transition.reset, f"{key}.reset", s, p, u), target.states, f"{key}.reset",
                            f"mode {target.name!r}")
        resets.append(ca.Function(f"{transition.label}_reset", [x, theta], [after]))
    x, s = state(model.section_mode)
    section_guard = ca.Function("section_guard", [x, theta],
                                [_guard(model.section.guard, x, s, p, u, "model.section.guard")])
    _direction(model.section.direction, "model.section")
    falls = {}
    for mode in model.modes:
        own = [f for f in model.falls if f.mode == mode.name]
        if own:
            x, s = state(mode)
            conditions = [_scalar(_call(f.condition, f"model.falls.{f.name}", s, p, u), f"model.falls.{f.name}")
                          for f in own]
            falls[mode.name] = ca.Function(f"{mode.name}_falls", [x, theta], [ca.vertcat(*conditions)])
    unknown = [f.name for f in model.falls if f.mode not in {m.name for m in model.modes}]
    if unknown:
        raise ModelError("model.falls", f"{unknown} name modes the model does not have")
    invariants = None
    held = model.invariants_of(law_name)
    if held:
        x, s = state(model.section_mode)
        invariants = ca.Function("invariants", [x, theta], [ca.vertcat(*[
            _scalar(_call(i.value, f"model.invariants.{i.name}", s, p, u), f"model.invariants.{i.name}")
            for i in held])])
    return ModelFunctions(model, law_name, theta_names, rhs, tuple(guards), tuple(resets), tuple(directions),
                          section_guard, falls, invariants, flows)


#: A closed-form flow solves its mode's equations when its rate is theirs to this, relative
#: to the rates' size, at the states :func:`_check_flow` tries.
FLOW_AGREEMENT = 1e-9


def _flow(mode: Mode, x: ca.SX, s: Names, theta: ca.SX, p: Names, u: Names) -> ca.Function:
    """The mode's closed-form flow as a Function (x, theta, t) -> x(t)."""
    key = f"model.modes.{mode.name}.flow"
    t = ca.SX.sym("t")
    after = _column(_call(mode.flow, key, s, p, u, t), mode.states, key, f"mode {mode.name}'s states")  # type: ignore[arg-type]
    return ca.Function(f"{mode.name}_flow", [x, theta, t], [after], ["x", "theta", "t"], ["x_t"])


def _check_flow(mode: Mode, flow: ca.Function, rhs: ca.Function, model: Model, law: str) -> None:
    """Refuse a closed-form flow that does not start at its state or whose rate is not the
    mode's equations of motion, at a few states (seeded) at the default body and controls,
    at t = 0 and a tenth of the body's time scale later."""
    key = f"model.modes.{mode.name}.flow"
    quantities = (*model.parameters, *model.controls_of(law))  # theta's order
    defaults = {q.name: q.default for q in quantities}
    theta = np.array([q.default for q in quantities])
    x, th, t = ca.SX.sym("x", flow.size1_in(0)), ca.SX.sym("theta", flow.size1_in(1)), ca.SX.sym("t")
    moved = flow(x, th, t)
    residual = ca.Function("flow_residual", [x, th, t], [ca.jacobian(moved, t) - rhs(moved, th), moved - x])
    rng = np.random.default_rng(12)
    for state in rng.uniform(0.3, 0.7, (3, flow.size1_in(0))):
        for time in (0.0, 0.1 * model.time_scale(defaults)):
            rate_error, start = (np.asarray(v).ravel() for v in residual(state, theta, time))
            size = max(1.0, float(np.max(np.abs(np.asarray(rhs(state, theta))))))
            if time == 0.0 and not np.max(np.abs(start)) <= FLOW_AGREEMENT * max(1.0, float(np.max(np.abs(state)))):
                raise ModelError(key, f"does not start at its state: at t = 0 it moves it by {np.max(np.abs(start)):.3g}")
            if not np.max(np.abs(rate_error)) <= FLOW_AGREEMENT * size:
                raise ModelError(key, f"does not solve the mode's equations of motion: its rate differs from "
                                      f"them by {np.max(np.abs(rate_error)):.3g} at t = {time:.3g} s")


def fall_names(model: Model, mode: str) -> tuple[str, ...]:
    """The names of ``mode``'s falls, in the order of its falls Function's entries."""
    return tuple(f.name for f in model.falls if f.mode == mode)
