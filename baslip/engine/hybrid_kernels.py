"""The generated pieces of a described model's stride, compiled to C as one library.

:class:`baslip.engine.hybrid.HybridMap` integrates each mode of a stride in DOP853 steps
and ends it on its guard. Calling the step once per step from Python costs more than the
step itself, so the steps are taken in *chunks* of :data:`CHUNK`: one call integrates
CHUNK steps of one size (a ``mapaccum`` loop, so the generated code holds one step) and
returns every node's state, the guard at every node and the mode's falls at every node a
step starts from. Python then finds the first node at which the mode fell, left the
finite numbers or crossed its guard, exactly as a step-by-step loop would.

A mode that gives its closed-form flow (``Mode(flow=...)``, such as the BA-SLIP's
ballistic flight) is stepped along it, exactly, instead of by DOP853. Per mode ``i`` of
the stride order the library holds:

* ``guard_i(x, theta)``: the guard that ends the mode;
* ``chunk_i(x, h, theta)``: CHUNK steps of size ``h``, as above;
* ``chunk_sens_i(x, J, h, theta)``: the same, carrying ``J = d x / d(X0, theta)`` (X0 the
  section coordinates at the stride's start) through the steps (each step's own
  derivatives, its size held fixed), with J at every node;
* ``run_i_n``, ``run_sens_i_n``: the same for the n steps of a mode's run, n in
  :data:`RUN_STEPS`, in one call;
* ``event_i(x, s0, theta)``: the last step, its size ``s`` solved by Newton from ``s0`` so
  that it ends on the guard (:func:`baslip.engine.dop853.event_step`);
* ``event_sens_i(x, J, s, theta)``: J carried through that step, the step's size moving
  with the state so that the guard stays at zero (the implicit-function theorem);

and per transition ``i`` the reset and the reset carrying J (``reset_i``,
``reset_sens_i``). The values are those of the same step, guard and reset Functions in
CasADi's virtual machine; only the Jacobian's sums may round differently.

The library's cache key holds the description's Functions, serialised, so a user's model
file needs no other key. Without a compiler the same Functions run in CasADi's virtual
machine, behind the same interface (:mod:`baslip.engine.native`).
"""

from __future__ import annotations

import hashlib
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca

from baslip.engine import dop853
from baslip.engine.codegen import compile_kernels, module_files
from baslip.engine.dop853 import DOP853, event_step, step_function
from baslip.engine.native import Kernel
from baslip.model.symbolic import ModelFunctions

#: Steps a chunk takes in one call.
CHUNK = 8
#: Forward directions a step's generated derivative takes at once (the step Function's
#: ``max_num_dir``, :func:`baslip.engine.dop853.step_function`).
DIRECTIONS = 4
#: Newton iterations of an event step (unrolled in its graph).
EVENT_ITERATIONS = 8
#: Step counts a mode's run takes in one call (``run_i_n``): those beyond one chunk that
#: :func:`baslip.engine.hybrid.calibrated_resolution` chooses but for the stiffest laws
#: (128 and 256 steps run in chunks: their call sites would cost every model's compile).
RUN_STEPS = (16, 32, 64)
#: The library's entry points per mode of the stride and per transition, by their prefix.
PHASE_PARTS = ("guard", "chunk", "chunk_sens", "event", "event_sens")
RESET_PARTS = ("reset", "reset_sens")


@dataclass(frozen=True)
class PhaseKernels:
    """The compiled pieces of one mode of the stride (see the module's docstring)."""

    guard: Kernel
    chunk: Kernel
    chunk_sens: Kernel
    event: Kernel
    event_sens: Kernel
    runs: Mapping[int, tuple[Kernel, Kernel]]

    def steps(self, count: int) -> tuple[Kernel, Kernel]:
        """The kernels (without, with J) that take ``count`` steps in one call, if the
        library has them, else the chunk's."""
        return self.runs.get(count, (self.chunk, self.chunk_sens))


@dataclass(frozen=True)
class ResetKernels:
    """The compiled reset of one transition, alone and carrying the Jacobian."""

    reset: Kernel
    reset_sens: Kernel


@dataclass(frozen=True)
class StrideKernels:
    """The compiled pieces of a whole stride: a phase per mode, a reset per transition."""

    phases: tuple[PhaseKernels, ...]
    resets: tuple[ResetKernels, ...]


def stride_kernels(functions: ModelFunctions, *, enabled: bool | None = None) -> StrideKernels:
    """The stride's kernels of ``functions``, compiled and cached (see the module's
    docstring); ``enabled`` as in :func:`baslip.engine.codegen.compile_kernels`."""
    kernels = compile_kernels(_library_name(functions), _names(functions), lambda: stride_functions(functions),
                              module_files(sys.modules[__name__], dop853), enabled=enabled,
                              settings=_description_key(functions))
    phases = tuple(PhaseKernels(**{part: kernels[f"{part}_{i}"] for part in PHASE_PARTS},
                                runs={n: (kernels[f"run_{i}_{n}"], kernels[f"run_sens_{i}_{n}"]) for n in RUN_STEPS})
                   for i in range(len(functions.model.order)))
    resets = tuple(ResetKernels(*(kernels[f"{part}_{i}"] for part in RESET_PARTS)) for i in range(len(functions.resets)))
    return StrideKernels(phases, resets)


def _names(functions: ModelFunctions) -> list[str]:
    """The library's entry points, as :func:`stride_functions` names them."""
    phases = [f"{part}_{i}" for i in range(len(functions.model.order)) for part in PHASE_PARTS]
    phases += [f"{part}_{i}_{n}" for i in range(len(functions.model.order)) for n in RUN_STEPS
               for part in ("run", "run_sens")]
    return phases + [f"{part}_{i}" for i in range(len(functions.resets)) for part in RESET_PARTS]


def _description_key(functions: ModelFunctions) -> str:
    """What the library's code derives from besides this module and the tableau: the
    description's Functions in the stride's order, serialised (CasADi's serialisation is
    deterministic; generating the C text to hash it would cost 0.3 s for the BA-SLIP)."""
    model = functions.model
    parts = [functions.rhs[m] for m in model.order] + [*functions.guards, functions.section_guard, *functions.resets]
    parts += [functions.falls[m] for m in model.order if m in functions.falls]
    parts += [functions.flows[m] for m in model.order if m in functions.flows]
    digest = hashlib.sha256()
    for function in parts:
        digest.update(function.serialize().encode())
    return digest.hexdigest()


def _library_name(functions: ModelFunctions) -> str:
    """A C identifier naming the model and its law (the cache key tells versions apart)."""
    return "hybrid_" + re.sub(r"[^A-Za-z0-9_]", "_", f"{functions.model.name}_{functions.law}")


def stride_functions(functions: ModelFunctions) -> list[ca.Function]:
    """Every Function of the stride's library, in the order of the stride, by the names
    the module's docstring gives (before compiling: to read or to generate)."""
    model = functions.model
    guards = [*functions.guards, functions.section_guard]
    state_columns = len(functions.model.section.coordinates)
    # One step per mode, so that a mode the stride visits twice is generated once.
    steps = {mode: _flow_step(functions.flows[mode]) if mode in functions.flows
             else step_function(functions.rhs[mode], tableau=DOP853) for mode in model.order}
    built: list[ca.Function] = []
    for i, (mode, guard) in enumerate(zip(model.order, guards)):
        rhs, step = functions.rhs[mode], steps[mode]
        falls = functions.falls.get(mode)
        block = _block(f"block_{i}", _one_step(f"step_{i}", step, guard, falls, None))
        block_sens = _block(f"block_sens_{i}", _one_step(f"step_sens_{i}", step, guard, falls, state_columns))
        built += [
            _renamed(f"guard_{i}", guard),
            _chunk(f"chunk_{i}", block),
            _chunk(f"chunk_sens_{i}", block_sens),
            _renamed(f"event_{i}", event_step(step, rhs, guard, EVENT_ITERATIONS)),
            _event_sens(f"event_sens_{i}", step, guard, state_columns),
        ]
        for n in RUN_STEPS:
            built += [_chunk(f"run_{i}_{n}", block, n), _chunk(f"run_sens_{i}_{n}", block_sens, n)]
    for i, reset in enumerate(functions.resets):
        built += [_renamed(f"reset_{i}", reset), _reset_sens(f"reset_sens_{i}", reset, state_columns)]
    return built


def _flow_step(flow: ca.Function) -> ca.Function:
    """A step of size ``h`` along a mode's closed-form flow, exact at any size, with the
    DOP853 step's signature: (x, h, theta) -> (x_next, error), its error zero."""
    x = ca.SX.sym("x", flow.size1_in(0))
    h = ca.SX.sym("h")
    theta = ca.SX.sym("theta", flow.size1_in(1))
    return ca.Function(f"{flow.name()}_step", [x, h, theta], [flow(x, theta, h), ca.SX(1, 1)],
                       ["x", "h", "theta"], ["x_next", "error"], {"max_num_dir": DIRECTIONS})


def _renamed(name: str, function: ca.Function) -> ca.Function:
    """``function`` under ``name``, called (not inlined), with its inputs and outputs."""
    inputs = [function.mx_in(k) for k in range(function.n_in())]
    return ca.Function(name, inputs, function.call(inputs), function.name_in(), function.name_out())


def _one_step(name: str, step: ca.Function, guard: ca.Function, falls: ca.Function | None,
              state_columns: int | None) -> ca.Function:
    """One step of a chunk: (x, [J,] h, theta) -> (x_next, [J_next,] the guard at x_next,
    the falls at x). J is carried when ``state_columns`` (how many of its columns belong to
    the start's section coordinates) is given."""
    x = ca.MX.sym("x", step.size1_in(0))
    h = ca.MX.sym("h")
    theta = ca.MX.sym("theta", step.size1_in(2))
    x_next = step(x, h, theta)[0]
    fallen = falls(x, theta) if falls is not None else ca.MX(0, 1)
    carried_in, carried_out = [], []
    if state_columns is not None:
        carried = ca.MX.sym("J", x.numel(), state_columns + theta.numel())
        carried_in = [carried]
        carried_out = [_moved(step, [x, h, theta], carried, state_columns)]
    return ca.Function(name, [x, *carried_in, h, theta], [x_next, *carried_out, guard(x_next, theta), fallen])


def _block(name: str, one: ca.Function) -> ca.Function:
    """CHUNK steps of ``one`` (:func:`_one_step`): (x, [J,] h, theta) -> (the last node, [J
    there,] the nodes, [J at the nodes,] the guards, the falls)."""
    inputs, outputs = _looped(name, one, CHUNK)
    ends = [outputs[0][:, -1]]
    if len(inputs) == 4:  # J at the last node: the last of the side-by-side blocks
        ends.append(outputs[1][:, -inputs[1].size2():])
    return ca.Function(name, inputs, [*ends, *outputs])


def _chunk(name: str, block: ca.Function, count: int = CHUNK) -> ca.Function:
    """``count`` steps of one size (a multiple of CHUNK, in blocks of :func:`_block`): the
    nodes, J at the nodes if the block carries it, the guard at the nodes and the falls at
    the nodes each step starts from (see the module's docstring). The generated code calls
    the block count / CHUNK times in a row, so a long run costs the compiler little."""
    inputs, outputs = _looped(name, block, count // CHUNK)
    carries = len(inputs) == 4
    names = ["nodes", *(["carried"] if carries else []), "guards", "falls"]
    return ca.Function(name, inputs, outputs[1 + carries:], ["x", *(["J"] if carries else []), "h", "theta"], names)


def _looped(name: str, function: ca.Function, count: int) -> tuple[list[ca.MX], list[ca.MX]]:
    """``function`` of (x, [J,] h, theta) called ``count`` times in a row, x (and J) handed
    on: its inputs (x, [J,] h, theta) and ``mapaccum``'s outputs (the handed-on values
    after each call, then the other outputs side by side)."""
    carries = function.n_in() == 4
    accumulated = [0, 1] if carries else [0]
    looped = function.mapaccum(f"{name}_loop", count, accumulated, accumulated)
    start = [ca.MX.sym("x", function.size1_in(0))] + ([ca.MX.sym("J", function.sparsity_in(1))] if carries else [])
    size, parameters = ca.MX.sym("h"), ca.MX.sym("theta", function.size1_in(function.n_in() - 1))
    outputs = looped(*start, ca.repmat(size, 1, count), ca.repmat(parameters, 1, count))
    return [*start, size, parameters], list(outputs)


def _moved(function: ca.Function, inputs: list[ca.MX], carried: ca.MX, state_columns: int,
           along_size: int | None = None) -> ca.MX:
    """d out / d(X0, theta), ``out`` the first output of ``function(x, ..., theta)`` (the
    state first, theta last among ``inputs``), from J = d x / d(X0, theta); with
    ``along_size`` (the index of an input), a last column along that input too.

    The columns are taken by the Function's forward derivative in batches of
    :data:`DIRECTIONS`, the last padded with zeros, so that the generated code holds the
    derivative once (a smaller last batch would add another, as large). Expanding the
    Jacobian in SX instead made the BA-SLIP's library take 309 s to compile, not 20 s."""
    # Called explicitly, not through jtimes: jtimes with a seed whose padding columns are
    # zero returned zeros in every direction (CasADi 3.8.2).
    x, theta = inputs[0], inputs[-1]
    columns = state_columns + theta.numel() + (along_size is not None)
    seeds = [ca.MX.zeros(value.sparsity().size1(), columns) for value in inputs]
    seeds[0] = ca.horzcat(carried, ca.MX.zeros(x.numel(), columns - carried.size2()))
    seeds[-1] = ca.horzcat(ca.MX.zeros(theta.numel(), state_columns), ca.MX.eye(theta.numel()),
                           ca.MX.zeros(theta.numel(), columns - state_columns - theta.numel()))
    if along_size is not None:
        seeds[along_size] = ca.horzcat(ca.MX.zeros(1, columns - 1), ca.MX.ones(1, 1))
    batch = min(DIRECTIONS, columns)
    forward = function.forward(batch)
    nominal = [ca.MX(function.sparsity_out(k).size1(), function.sparsity_out(k).size2())
               for k in range(function.n_out())]
    blocks = []
    for first in range(0, columns, batch):
        taken = min(batch, columns - first)
        block = [ca.horzcat(seed[:, first:first + taken], ca.MX.zeros(seed.size1(), batch - taken)) for seed in seeds]
        blocks.append(forward.call([*inputs, *nominal, *block])[0][:, :taken])
    return ca.horzcat(*blocks)


def _event_sens(name: str, step: ca.Function, guard: ca.Function, state_columns: int) -> ca.Function:
    """J through the step of size ``s`` that ends on the guard, ``s`` moving with (X0,
    theta) so that the guard stays at zero."""
    x = ca.MX.sym("x", step.size1_in(0))
    s = ca.MX.sym("s")
    theta = ca.MX.sym("theta", step.size1_in(2))
    carried = ca.MX.sym("J", x.numel(), state_columns + theta.numel())
    x_end = step(x, s, theta)[0]
    both = _moved(step, [x, s, theta], carried, state_columns, along_size=1)
    moved, by_size = both[:, :-1], both[:, -1]
    y = ca.SX.sym("y", x.numel())
    theta_sx = ca.SX.sym("theta", theta.numel())
    g = guard(y, theta_sx)
    slopes = ca.Function(f"{name}_guard", [y, theta_sx], [ca.jacobian(g, y), ca.jacobian(g, theta_sx)])
    g_state, g_theta = slopes(x_end, theta)
    rate = ca.mtimes(g_state, by_size)
    shift = -(ca.mtimes(g_state, moved) + ca.horzcat(ca.MX(1, state_columns), g_theta)) / rate
    return ca.Function(name, [x, carried, s, theta], [moved + ca.mtimes(by_size, shift)], ["x", "J", "s", "theta"],
                       ["carried"])


def _reset_sens(name: str, reset: ca.Function, state_columns: int) -> ca.Function:
    """The reset and J carried through it."""
    x = ca.MX.sym("x", reset.size1_in(0))
    theta = ca.MX.sym("theta", reset.size1_in(1))
    carried = ca.MX.sym("J", x.numel(), state_columns + theta.numel())
    after = reset(x, theta)
    return ca.Function(name, [x, carried, theta], [after, _moved(reset, [x, theta], carried, state_columns)],
                       ["x", "J", "theta"], ["after", "carried"])
