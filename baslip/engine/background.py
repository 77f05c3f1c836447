"""A library compiled on another core while the process goes on.

A first run on a new machine spends most of its time in gcc, one library after the
other, on one core. A library that is needed only later (the engine's Jacobians, say,
which a solve first asks for after IPOPT has run) can be compiled in a thread while the
process builds and compiles the rest: gcc runs as its own process, so the two builds use
both cores. The symbolic functions and their C are made in the calling thread (CasADi's
objects are not shared between threads); the thread only compiles and loads.
"""

from __future__ import annotations

import pathlib
import threading
from collections.abc import Callable, Sequence

import casadi as ca

from baslip.engine.codegen import (
    FEW_CALLS,
    OPTIMISATION,
    QUICK_OPTIMISATION,
    cached_kernels,
    compile_kernels,
    compiling,
    generate_c,
    note_switched_off,
)
from baslip.engine.native import Kernel
from baslip.engine.setuptime import setting_up


class KernelsLater:
    """The kernels of :func:`~baslip.engine.codegen.compile_kernels`, compiled in a thread
    when the cache lacks them, and waited for on first use; or none at all with compiling
    switched off: the caller then builds only the functions it uses, in the virtual
    machine, when it uses them.

    Parameters
    ----------
    name, names, build, sources, settings, optimisation, enabled
        As :func:`~baslip.engine.codegen.compile_kernels`.
    """

    def __init__(self, name: str, names: Sequence[str], build: Callable[[], Sequence[ca.Function]],
                 sources: Sequence[pathlib.Path], *, settings: str = "", optimisation: str = OPTIMISATION,
                 enabled: bool | str | None = None):
        self._kernels: dict[str, Kernel] | None = None
        self._failure: BaseException | None = None
        self._thread: threading.Thread | None = None
        if not compiling(enabled):  # the caller's functions in the virtual machine
            note_switched_off(name, enabled)
            return
        self._kernels = cached_kernels(name, names, sources, settings=settings, optimisation=optimisation)
        if self._kernels is None and enabled == FEW_CALLS:
            optimisation = QUICK_OPTIMISATION
            self._kernels = cached_kernels(name, names, sources, settings=settings, optimisation=optimisation)
        if self._kernels is not None:
            return
        functions = build()
        generated = generate_c(name, functions)

        def compile_now() -> None:
            try:
                self._kernels = compile_kernels(name, names, lambda: functions, sources, enabled=enabled,
                                                settings=settings, optimisation=optimisation, generated=generated)
            except BaseException as error:  # handed to the thread that waits for the kernels
                self._failure = error

        self._thread = threading.Thread(target=compile_now, name=f"compile-{name}", daemon=True)
        self._thread.start()

    def get(self) -> dict[str, Kernel] | None:
        """The kernels, once their library is compiled and loaded (or their fallback); None
        where the caller's functions are to run in the virtual machine."""
        if self._thread is not None:
            with setting_up():  # waiting for the library counts as set-up, not as work
                self._thread.join()
            self._thread = None
        if self._failure is not None:
            raise self._failure
        return self._kernels
