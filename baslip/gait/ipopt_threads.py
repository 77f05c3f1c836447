"""IPOPT's dense linear algebra on one thread: the same iterates on every machine.

CasADi's IPOPT factorises its KKT systems with MUMPS over CasADi's own OpenBLAS, which
by default starts a thread per core. Where IPOPT struggles (inertia corrections with
regularisations up to 1e16, hundreds of iterations), the iterates then depend on the
thread count: on the 2-core machine, an exact-Hessian solve of a `body_angle_scan` point
that fails after 300 iterations ends 1.4 rad/s apart in theta_h_dot on 1 and on 2
threads (stopped at 200 iterations, the two are the same to the bit). Ordinary solves
are the same to the bit either way. The second thread also buys no speed: at the NLP's
sizes it spins while it waits, and in a study with one solver per core it takes its
cycles from the other lane (`body_angle_scan`: 9.7 s of system time, 34.9 s in all,
against 1.0 s and 29.9 s on one thread).

So every IPOPT solve runs its BLAS on one thread, whatever the machine offers.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os

import casadi as ca

#: The file names of CasADi's bundled OpenBLAS, as its wheels name it. A wheel holds
#: several copies (one per link name, not symbolic links), and the dynamic loader keeps
#: apart copies loaded under different names, so only the ones already loaded (the copy
#: IPOPT's plugin linked) are told.
OPENBLAS_PATTERN = "libcasadi-tp-openblas*"


@functools.cache
def openblas_files() -> tuple[str, ...]:
    """The files of CasADi's bundled OpenBLAS (none where this CasADi ships none)."""
    return tuple(sorted(glob.glob(os.path.join(os.path.dirname(ca.__file__), OPENBLAS_PATTERN))))


def loaded_openblas() -> list[ctypes.CDLL]:
    """The copies of CasADi's OpenBLAS loaded in this process, as libraries to call."""
    loaded: list[ctypes.CDLL] = []
    no_load = getattr(os, "RTLD_NOLOAD", None)  # POSIX only; elsewhere nothing is told
    if no_load is None:
        return loaded
    for library in openblas_files():
        try:
            handle = ctypes.CDLL(library, mode=no_load)  # only a copy already loaded
        except OSError:
            continue
        if hasattr(handle, "openblas_set_num_threads"):
            loaded.append(handle)
    return loaded


def pin_ipopt_threads() -> list[int]:
    """Set IPOPT's BLAS to one thread, once its plugin is loaded (after the solver is
    built, before each solve: another part of the process, such as a user's own CasADi
    code, may change the count in between). Returns the thread count each loaded copy now
    reports (empty where there is none: the BLAS then keeps its own threads)."""
    counts = []
    for library in loaded_openblas():
        library.openblas_set_num_threads(1)
        counts.append(int(library.openblas_get_num_threads()))
    return counts
