"""The generated pieces of a described model's stride, compiled to C as one library.

:class:`baslip.engine.hybrid.HybridMap` integrates each mode of a stride in DOP853 steps
and ends it on its guard. Calling the step once per step from Python costs more than the
step itself, so the steps are taken in *chunks* of :data:`CHUNK`: one call integrates
CHUNK steps of one size (a ``mapaccum`` loop, so the generated code holds one step) and
returns every node's state, the guard at every node and the mode's falls at every node a
step starts from, and the first step that stopped the mode: one that fell, left the
finite numbers or crossed its guard, exactly as a step-by-step loop would find it.

A mode that gives its closed-form flow (``Mode(flow=...)``, such as the BA-SLIP's
ballistic flight) is stepped along it, exactly, instead of by DOP853. Per mode ``i`` of
the stride order the library holds:

* ``chunk_i(x, h, theta)``: CHUNK steps of size ``h``, as above, and the guard at x;
* ``run_i_n``: the same for the n steps of a mode's run, n in :data:`RUN_STEPS`, in one
  call;
* ``event_i(x, s0, theta)``: the last step, its size ``s`` solved by Newton from ``s0`` so
  that it ends on the guard (:func:`baslip.engine.dop853.event_step`), and the state after
  the reset of the transition that follows;
* ``adjoint_i_n(A, G, x, s, event, starts, active, h, theta)``, n in
  :data:`ADJOINT_STEPS`: the Jacobian's adjoint sweep back through a mode. ``A`` (one
  column per row of the Jacobian) becomes A^T d x_end / d x_start and ``G`` gains A^T d
  x_end / d theta: first through the step of size ``s`` from ``x`` that ends on the guard,
  ``s`` moving with the state and theta so that the guard stays at zero (the
  implicit-function theorem), unless ``event`` is 0; then back through n steps of size
  ``h`` (their start states, last step first, as the columns of ``starts``), each step's
  size held fixed. A column whose ``active`` is 0 is skipped exactly, so that any count of
  steps up to n takes one call;

per transition ``i`` the reset's adjoint, ``reset_adjoint_i(x, A, theta)``; and the whole
stride in one call, ``stride_n(x, h_scout, theta)`` for n in :data:`MODE_STEPS`: each
mode's scout, the scout's event, its run of n steps and the run's event and reset, each
loop stopping at its first stopping step (a short-circuit switch skips the steps after
it), the modes one after the other. Its numbers are those of the calls above wherever each
scout needs at most :data:`SCOUT_STEPS` steps and each run n + :data:`RUN_MARGIN`. The
values are those of the same step, guard and reset Functions in CasADi's virtual machine.

The Jacobian is swept backwards because it has as many rows as the section has
coordinates (4 for the BA-SLIP) and far more columns (those and theta: 15): one reverse
derivative of a step with 4 directions costs about what one forward derivative with 4
costs, and carrying the 15 columns forwards took four of those.

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
#: Newton iterations of an event step (unrolled in its graph).
EVENT_ITERATIONS = 8
#: Step counts a mode's run takes in one call (``run_i_n``): those beyond one chunk that
#: :func:`baslip.engine.hybrid.calibrated_resolution` chooses but for the stiffest laws
#: (128 and 256 steps run in chunks: their call sites would cost every model's compile).
RUN_STEPS = (16, 32, 64)
#: Each mode in the whole stride's call (``stride_n``): its scout takes at most this many
#: steps, and its run of n steps this many more than n (the scout's duration is off by its
#: own error); from a mode that needs more on, the modes take their separate calls.
SCOUT_STEPS = 64
RUN_MARGIN = CHUNK
#: The step counts n of the modes' runs for which the library holds the whole stride's
#: call: every count :func:`baslip.engine.hybrid.calibrated_resolution` chooses but the
#: stiffest.
MODE_STEPS = (CHUNK, *RUN_STEPS)
#: Step counts an adjoint sweep takes in one call (``adjoint_i_n``), at most: a mode's
#: fixed steps (its run's, less the event's) are swept in as few calls as these allow.
ADJOINT_STEPS = (CHUNK, *RUN_STEPS)
#: The library's entry points per mode of the stride and per transition, by their prefix.
PHASE_PARTS = ("chunk", "event")
RESET_PARTS = ("reset_adjoint",)


@dataclass(frozen=True)
class PhaseKernels:
    """The compiled pieces of one mode of the stride (see the module's docstring)."""

    chunk: Kernel
    event: Kernel
    runs: Mapping[int, Kernel]
    adjoints: Mapping[int, Kernel]

    def steps(self, count: int) -> Kernel:
        """The kernel that takes ``count`` steps in one call, if the library has one, else
        the chunk."""
        return self.runs.get(count, self.chunk)

    def adjoint_calls(self, count: int) -> list[tuple[Kernel, int, int]]:
        """The adjoint kernels that sweep back through a mode's event step and ``count``
        steps, each with its columns and how many of them are steps (the rest are
        skipped): one call up to the longest."""
        calls: list[tuple[Kernel, int, int]] = []
        while count > 0 or not calls:  # a mode's event step alone takes a call too
            n = next((n for n in ADJOINT_STEPS if n >= count), ADJOINT_STEPS[-1])
            calls.append((self.adjoints[n], n, min(n, count)))
            count -= n
        return calls


@dataclass(frozen=True)
class ResetKernels:
    """The compiled adjoint of one transition's reset (the reset itself ends its mode's
    event)."""

    reset_adjoint: Kernel


@dataclass(frozen=True)
class StrideKernels:
    """The compiled pieces of a whole stride: a phase per mode, a reset per transition, and
    the stride in one call per step count of its modes' runs."""

    phases: tuple[PhaseKernels, ...]
    resets: tuple[ResetKernels, ...]
    strides: Mapping[int, Kernel]


def stride_kernels(functions: ModelFunctions, *, enabled: bool | None = None) -> StrideKernels:
    """The stride's kernels of ``functions``, compiled and cached (see the module's
    docstring); ``enabled`` as in :func:`baslip.engine.codegen.compile_kernels`."""
    kernels = compile_kernels(_library_name(functions), _names(functions), lambda: stride_functions(functions),
                              module_files(sys.modules[__name__], dop853), enabled=enabled,
                              settings=_description_key(functions))
    phases = tuple(PhaseKernels(**{part: kernels[f"{part}_{i}"] for part in PHASE_PARTS},
                                runs={n: kernels[f"run_{i}_{n}"] for n in RUN_STEPS},
                                adjoints={n: kernels[f"adjoint_{i}_{n}"] for n in ADJOINT_STEPS})
                   for i in range(len(functions.model.order)))
    resets = tuple(ResetKernels(*(kernels[f"{part}_{i}"] for part in RESET_PARTS)) for i in range(len(functions.resets)))
    return StrideKernels(phases, resets, {n: kernels[f"stride_{n}"] for n in MODE_STEPS})


def _names(functions: ModelFunctions) -> list[str]:
    """The library's entry points, as :func:`stride_functions` names them."""
    modes = range(len(functions.model.order))
    names = [f"{part}_{i}" for i in modes for part in PHASE_PARTS]
    names += [f"run_{i}_{n}" for i in modes for n in RUN_STEPS]
    names += [f"adjoint_{i}_{n}" for i in modes for n in ADJOINT_STEPS]
    names += [f"stride_{n}" for n in MODE_STEPS]
    return names + [f"{part}_{i}" for i in range(len(functions.resets)) for part in RESET_PARTS]


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
    directions = [*functions.directions, model.section.direction]
    rows = len(functions.model.section.coordinates)  # the Jacobian's rows: the adjoint's directions
    # One step per dynamics, so that a mode the stride visits twice, or two modes with the
    # same equations (the BA-SLIP's compression and decompression), are generated once.
    by_dynamics: dict[str, ca.Function] = {}
    steps = {}
    for mode in model.order:
        flows = mode in functions.flows
        dynamics = functions.flows[mode] if flows else functions.rhs[mode]
        key = ("flow" if flows else "rhs") + _canonical(dynamics)
        if key not in by_dynamics:
            by_dynamics[key] = _flow_step(dynamics) if flows else step_function(dynamics, tableau=DOP853)
        steps[mode] = by_dynamics[key]
    built: list[ca.Function] = []
    whole_modes: dict[int, list[ca.Function]] = {n: [] for n in MODE_STEPS}
    for i, (mode, guard) in enumerate(zip(model.order, guards)):
        rhs, step = functions.rhs[mode], steps[mode]
        falls = functions.falls.get(mode)
        one = _one_step(f"step_{i}", step, guard, falls, directions[i])
        block = _block(f"block_{i}", one, accumulated=2)
        adjoint_block = _block(f"adjoint_block_{i}", _adjoint_step(f"adjoint_step_{i}", step, rows),
                               accumulated=2, mapped=2)
        event_adjoint = _event_adjoint(f"event_adjoint_{i}", step, guard, rows)
        event = _event_then_reset(f"event_{i}", event_step(step, rhs, guard, EVENT_ITERATIONS),
                                  functions.resets[i] if i < len(functions.resets) else None)
        stepping = _block(f"stepping_block_{i}", _stepping(f"stepping_{i}", one), accumulated=6)
        scout = _stopping_loop(f"scout_{i}", stepping, SCOUT_STEPS)
        built += [_chunk(f"chunk_{i}", block, guard), event]
        built += [_chunk(f"run_{i}_{n}", block, guard, n) for n in RUN_STEPS]
        for n in MODE_STEPS:
            whole_modes[n].append(_whole_mode(f"mode_{i}_{n}", scout, stepping, event, guard, falls, n))
        built += [_adjoint_sweep(f"adjoint_{i}_{n}", event_adjoint, adjoint_block, n) for n in ADJOINT_STEPS]
    for i, reset in enumerate(functions.resets):
        built.append(_reset_adjoint(f"reset_adjoint_{i}", reset, rows))
    return built + [_whole_stride(f"stride_{n}", whole_modes[n]) for n in MODE_STEPS]


def _canonical(function: ca.Function) -> str:
    """``function``'s expressions, serialised under fixed names: equal for two Functions
    that compute the same graph whatever they are called."""
    inputs = [ca.SX.sym(f"i{k}", function.sparsity_in(k)) for k in range(function.n_in())]
    return ca.Function("dynamics", inputs, function.call(inputs)).serialize()


def _event_then_reset(name: str, event: ca.Function, reset: ca.Function | None) -> ca.Function:
    """The event step's outputs (:func:`baslip.engine.dop853.event_step`) and the state
    after the transition's reset (the state on the guard itself where none follows)."""
    inputs = [event.mx_in(k) for k in range(event.n_in())]
    outputs = event.call(inputs)
    after = reset(outputs[1], inputs[2]) if reset is not None else outputs[1]
    return ca.Function(name, inputs, [*outputs, after], event.name_in(), [*event.name_out(), "after"])


def _flow_step(flow: ca.Function) -> ca.Function:
    """A step of size ``h`` along a mode's closed-form flow, exact at any size, with the
    DOP853 step's signature: (x, h, theta) -> (x_next, error), its error zero."""
    x = ca.SX.sym("x", flow.size1_in(0))
    h = ca.SX.sym("h")
    theta = ca.SX.sym("theta", flow.size1_in(1))
    return ca.Function(f"{flow.name()}_step", [x, h, theta], [flow(x, theta, h), ca.SX(1, 1)],
                       ["x", "h", "theta"], ["x_next", "error"])


def _one_step(name: str, step: ca.Function, guard: ca.Function, falls: ca.Function | None,
              direction: int) -> ca.Function:
    """One step of a chunk: (x, g, h, theta) -> (x_next, the guard g_next at x_next, the
    falls at x, whether the step stops the mode), g the guard at x. A step stops the mode
    if it fell (a fall negative at x), was lost (x_next not finite) or crossed the guard in
    ``direction`` (direction * g < 0 <= direction * g_next): 1.0 or 0.0."""
    x = ca.MX.sym("x", step.size1_in(0))
    g = ca.MX.sym("g")
    h = ca.MX.sym("h")
    theta = ca.MX.sym("theta", step.size1_in(2))
    x_next = step(x, h, theta)[0]
    g_next = guard(x_next, theta)
    fallen = falls(x, theta) if falls is not None else ca.MX(0, 1)
    return ca.Function(name, [x, g, h, theta], [x_next, g_next, fallen, _stops(fallen, x_next, g, g_next, direction)])


def _stops(fallen: ca.MX, x_next: ca.MX, g: ca.MX, g_next: ca.MX, direction: int) -> ca.MX:
    """1.0 where a step stops its mode, else 0.0: it fell (``fallen``, the falls at its
    start, has a negative entry), was lost (``x_next`` is not finite) or crossed the guard
    in ``direction`` (``g`` to ``g_next``)."""
    fell = ca.mmin(fallen) < 0 if fallen.numel() else ca.MX.zeros(1, 1)
    lost = 1 - ca.mmin(ca.fabs(x_next) < ca.inf)  # inf and nan fail the comparison
    crossed = ca.logic_and(direction * g < 0, direction * g_next >= 0)
    return ca.fmax(fell, ca.fmax(lost, crossed))


def _stepping(name: str, one: ca.Function) -> ca.Function:
    """One step of a whole mode's loop: (x_before, x, g_before, g, stopped, count, h,
    theta) -> the same after the step from x, g the guard at x. The step taken (``one``,
    :func:`_one_step`) hands on (x, x_next, g, g_next), whether it stopped the mode and the
    count of steps before the stopping one; once stopped, the loop holds its values and
    takes no more steps (a short-circuit switch), so that (x_before, x) end as the
    stopping step's start and end, and the count as its index."""
    x_before, x = ca.MX.sym("x_before", one.size1_in(0)), ca.MX.sym("x", one.size1_in(0))
    g_before, g, stopped, count, h = (ca.MX.sym(n) for n in ("g_before", "g", "stopped", "count", "h"))
    theta = ca.MX.sym("theta", one.size1_in(3))
    x_next, g_next, _, stop = one(x, g, h, theta)
    taken = ca.vertcat(x, x_next, g, g_next, stop, count + 1 - stop)
    held = ca.vertcat(x_before, x, g_before, g, stopped, count)
    n = x.numel()
    after = ca.vertsplit(ca.if_else(stopped, held, taken, True), [0, n, 2 * n, 2 * n + 1, 2 * n + 2, 2 * n + 3, 2 * n + 4])
    return ca.Function(name, [x_before, x, g_before, g, stopped, count, h, theta], after)


def _stopping_loop(name: str, block: ca.Function, count: int) -> ca.Function:
    """``count`` steps (a multiple of CHUNK) of :func:`_stepping`, in blocks of CHUNK
    (``block``, from :func:`_block`), so that the generated code holds count / CHUNK call
    sites: (x, g, h, theta) -> (x_before, x, g_before, g, stopped, count) after the loop,
    and the state after each step (frozen once stopped)."""
    x, g, h = ca.MX.sym("x", block.size1_in(0)), ca.MX.sym("g"), ca.MX.sym("h")
    theta = ca.MX.sym("theta", block.size1_in(7))
    inputs, outputs = _looped(name, block, count // CHUNK, accumulated=6)
    ends = [v[:, -inputs[k].size2():] for k, v in enumerate(outputs[:6])]
    states = outputs[6 + 1]  # of the blocks' per-step outputs, the second: x after each step
    loop = ca.Function(f"{name}_blocks", inputs, [*ends, states])
    return ca.Function(name, [x, g, h, theta], loop.call([x, x, g, g, ca.MX(0.0), ca.MX(0.0), h, theta]))


def _whole_mode(name: str, scout: ca.Function, block: ca.Function, event: ca.Function, guard: ca.Function,
                falls: ca.Function | None, steps: int) -> ca.Function:
    """A mode in one call, as :class:`baslip.engine.hybrid.HybridMap` takes it in several:
    from x, the ``scout`` (:func:`_stopping_loop`, SCOUT_STEPS steps of ``h_scout``) to its
    stopping step and its event, the duration T; then a run in steps of T / (steps - 1/2),
    up to RUN_MARGIN steps more, to its stopping step and its event and reset.

    Outputs the guard at x, then for the scout and the run in turn: whether it stopped, the
    count of steps before the stopping one, the falls at that step's start, its end, the
    event's step and residual and the guard at the step's start; then the run's step, the
    state on the guard, the state after the reset and the state after each step."""
    x, h_scout, theta = ca.MX.sym("x", block.size1_in(0)), ca.MX.sym("h_scout"), ca.MX.sym("theta", block.size1_in(7))
    g_start = guard(x, theta)
    outputs: list[ca.MX] = [g_start]
    before, end, g_before, g, stopped, count, _ = scout.call([x, g_start, h_scout, theta])
    s, _, residual, *_ = event(before, h_scout * g_before / (g_before - g), theta)
    fallen = falls(before, theta) if falls is not None else ca.MX(0, 1)
    outputs += [stopped, count, fallen, end, s, residual, g_before]
    h_run = (count * h_scout + s) / (steps - 0.5)
    run = _stopping_loop(f"{name}_run", block, steps + RUN_MARGIN)
    before, end, g_before, g, stopped, count, nodes = run.call([x, g_start, h_run, theta])
    s, x_end, residual, *_, after = event(before, h_run * g_before / (g_before - g), theta)
    fallen = falls(before, theta) if falls is not None else ca.MX(0, 1)
    outputs += [stopped, count, fallen, end, s, residual, g_before, h_run, x_end, after, nodes]
    return ca.Function(name, [x, h_scout, theta], outputs)


def _block(name: str, one: ca.Function, accumulated: int = 1, mapped: int = 0) -> ca.Function:
    """CHUNK calls of ``one`` in a row, as :func:`_looped` makes them: (the handed-on
    values after the last call, then ``mapaccum``'s outputs)."""
    inputs, outputs = _looped(name, one, CHUNK, accumulated, mapped)
    ends = [outputs[k][:, -inputs[k].size2():] for k in range(accumulated)]
    return ca.Function(name, inputs, [*ends, *outputs])


def _chunk(name: str, block: ca.Function, guard: ca.Function, count: int = CHUNK) -> ca.Function:
    """``count`` steps of one size (a multiple of CHUNK, in blocks of :func:`_block`) from
    x: the nodes, the guard at the nodes, the falls at the nodes each step starts from, the
    guard at x and the first step that stopped the mode (:func:`_one_step`; ``count`` if
    none did). The generated code calls the block count / CHUNK times in a row, so a long
    run costs the compiler little."""
    x, h, theta = ca.MX.sym("x", block.size1_in(0)), ca.MX.sym("h"), ca.MX.sym("theta", block.size1_in(3))
    g_start = guard(x, theta)
    inputs, outputs = _looped(name, block, count // CHUNK, accumulated=2)
    nodes, guards, falls, stops = ca.Function(f"{name}_steps", inputs, outputs[2:]).call([x, g_start, h, theta])
    # The first stopping step k is count - max over stopping steps of (count - k).
    first = count - ca.mmax(stops * ca.DM(range(count, 0, -1)).T)
    return ca.Function(name, [x, h, theta], [nodes, guards, falls, g_start, first],
                       ["x", "h", "theta"], ["nodes", "guards", "falls", "g_start", "stop"])


def _adjoint_sweep(name: str, event_adjoint: ca.Function, block: ca.Function, count: int) -> ca.Function:
    """The adjoint back through a mode's event step (unless ``event`` is 0), then through
    ``count`` steps (a multiple of CHUNK, in blocks of CHUNK): (A, G, x, s, event, starts,
    active, h, theta) -> (A, G) at the first step's start (see the module's docstring)."""
    adjoint, gathered = ca.MX.sym("A", block.sparsity_in(0)), ca.MX.sym("G", block.sparsity_in(1))
    x, s, event = ca.MX.sym("x", block.size1_in(2)), ca.MX.sym("s"), ca.MX.sym("event")
    inputs, outputs = _looped(name, block, count // CHUNK, accumulated=2, mapped=2)
    theta = inputs[-1]
    through_event, added = event_adjoint(x, s, adjoint, theta)
    start = [ca.if_else(event, through_event, adjoint), ca.if_else(event, gathered + added, gathered)]
    swept = ca.Function(f"{name}_steps", inputs, [outputs[k][:, -inputs[k].size2():] for k in range(2)])
    return ca.Function(name, [adjoint, gathered, x, s, event, *inputs[2:]], swept.call([*start, *inputs[2:]]),
                       ["A", "G", "x", "s", "event", "starts", "active", "h", "theta"], ["A_before", "G_after"])


def _whole_stride(name: str, modes: list[ca.Function]) -> ca.Function:
    """The stride in one call: (x, h_scout, theta) -> each mode's outputs (:func:`_whole_mode`)
    in the stride's order, a mode starting from the state after the reset that ended the
    one before it."""
    x, h_scout, theta = modes[0].mx_in()
    outputs: list[ca.MX] = []
    start = x
    for mode in modes:
        outputs += mode.call([start, h_scout, theta])
        start = outputs[-2]  # the state after the reset
    return ca.Function(name, [x, h_scout, theta], outputs)


def _looped(name: str, function: ca.Function, count: int, accumulated: int = 1,
            mapped: int = 0) -> tuple[list[ca.MX], list[ca.MX]]:
    """``function`` called ``count`` times in a row: its first ``accumulated`` inputs handed
    on from each call's first outputs, its next ``mapped`` inputs given ``count`` times as
    wide (each call its share of the columns), the others the same in every call. Returns
    the inputs and ``mapaccum``'s outputs (the handed-on values after each call, then the
    other outputs, side by side)."""
    handed, split = list(range(accumulated)), range(accumulated, accumulated + mapped)
    looped = function.mapaccum(f"{name}_loop", count, handed, handed)
    inputs = [ca.MX.sym(f"i{k}", function.size1_in(k), function.size2_in(k) * (count if k in split else 1))
              for k in range(function.n_in())]
    same = inputs[accumulated + mapped:]
    outputs = looped(*inputs[:accumulated + mapped], *(ca.repmat(v, 1, count) for v in same))
    return inputs, list(outputs)


def _pulled(function: ca.Function, inputs: list[ca.MX], adjoint: ca.MX) -> list[ca.MX]:
    """A^T d out / d(each input), ``out`` the first output of ``function``, one column of
    ``adjoint`` (A) per direction: the Function's reverse derivative, its other outputs'
    seeds zero."""
    directions = adjoint.size2()
    reverse = function.reverse(directions)
    nominal = [ca.MX(function.size1_out(k), function.size2_out(k)) for k in range(function.n_out())]
    seeds = [adjoint] + [ca.MX(function.size1_out(k), function.size2_out(k) * directions)
                         for k in range(1, function.n_out())]
    return reverse.call([*inputs, *nominal, *seeds])


def _adjoint_step(name: str, step: ca.Function, rows: int) -> ca.Function:
    """One step of the adjoint sweep: (A, G, x, active, h, theta) -> (A^T d x_next / d x,
    G + A^T d x_next / d theta) at the step from ``x``, or (A, G) where ``active`` is 0."""
    x = ca.MX.sym("x", step.size1_in(0))
    h = ca.MX.sym("h")
    theta = ca.MX.sym("theta", step.size1_in(2))
    adjoint = ca.MX.sym("A", x.numel(), rows)
    gathered = ca.MX.sym("G", theta.numel(), rows)
    active = ca.MX.sym("active")
    by_state, _, by_theta = _pulled(step, [x, h, theta], adjoint)
    return ca.Function(name, [adjoint, gathered, x, active, h, theta],
                       [ca.if_else(active, by_state, adjoint), ca.if_else(active, gathered + by_theta, gathered)])


def _event_adjoint(name: str, step: ca.Function, guard: ca.Function, rows: int) -> ca.Function:
    """The adjoint through the step of size ``s`` that ends on the guard, ``s`` moving with
    the state and theta so that the guard stays at zero: (x, s, A, theta) -> (A', G').

    With x_end = step(x, s), f = d x_end / d s and the guard's slopes g_x, g_theta at x_end,
    ds = -(g_x d x_end + g_theta d theta) / (g_x f) along the guard, so A^T d x_end is
    M^T (d step / d(x, theta)) with M = A - g_x^T (f^T A) / (g_x f), less (f^T A) / (g_x f)
    g_theta for theta."""
    x = ca.MX.sym("x", step.size1_in(0))
    s = ca.MX.sym("s")
    theta = ca.MX.sym("theta", step.size1_in(2))
    adjoint = ca.MX.sym("A", x.numel(), rows)
    x_end = step(x, s, theta)[0]
    nominal = [ca.MX(step.size1_out(k), step.size2_out(k)) for k in range(step.n_out())]
    along_size = step.forward(1).call([x, s, theta, *nominal, ca.MX(x.numel(), 1), ca.MX.ones(1, 1),
                                       ca.MX(theta.numel(), 1)])[0]
    y = ca.SX.sym("y", x.numel())
    theta_sx = ca.SX.sym("theta", theta.numel())
    g = guard(y, theta_sx)
    slopes = ca.Function(f"{name}_guard", [y, theta_sx], [ca.jacobian(g, y), ca.jacobian(g, theta_sx)])
    g_state, g_theta = slopes(x_end, theta)
    shares = ca.mtimes(along_size.T, adjoint) / ca.mtimes(g_state, along_size)  # (f^T A) / (g_x f), a row
    by_state, _, by_theta = _pulled(step, [x, s, theta], adjoint - ca.mtimes(g_state.T, shares))
    return ca.Function(name, [x, s, adjoint, theta], [by_state, by_theta - ca.mtimes(g_theta.T, shares)],
                       ["x", "s", "A", "theta"], ["A_before", "G"])


def _reset_adjoint(name: str, reset: ca.Function, rows: int) -> ca.Function:
    """The adjoint through the reset: (x, A, theta) -> (A^T d reset / d x, A^T d reset / d theta)."""
    x = ca.MX.sym("x", reset.size1_in(0))
    theta = ca.MX.sym("theta", reset.size1_in(1))
    adjoint = ca.MX.sym("A", reset.size1_out(0), rows)
    by_state, by_theta = _pulled(reset, [x, theta], adjoint)
    return ca.Function(name, [x, adjoint, theta], [by_state, by_theta], ["x", "A", "theta"], ["A_before", "G"])
