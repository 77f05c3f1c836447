"""Child processes that end with the process that started them, however it ends.

Two kinds of children are started by baslip: the worker processes of a study and the C
compiler. Both must die with their parent, even when the parent is killed with SIGKILL
and so runs no clean-up of its own. On Linux the kernel does it: a process can ask for a
signal when its parent ends (``PR_SET_PDEATHSIG``). The request must come first, before
anything slow, and the parent checked once more after it, because a parent that ended
before the request was made sends no signal.

This module imports nothing heavy on purpose: a spawned worker imports it first (its
entry point is :func:`run_pickled`), sets the request, and only then unpickles and
imports the work it was given.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import threading

#: prctl's option number for the parent-death signal (linux/prctl.h).
_PR_SET_PDEATHSIG = 1


def ask_for_death_signal(sig: int, parent_pid: int) -> None:
    """Have the kernel send ``sig`` to this process when its parent ends; end at once if
    the parent (whose pid was ``parent_pid``) has already gone. Without prctl (not
    Linux), only the check is made."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, sig)
    if os.getppid() != parent_pid:
        os._exit(1)


def die_with_parent() -> None:
    """Make this spawned worker end when the process that started it ends: the kernel's
    parent-death signal on Linux, and a watcher thread on the parent's sentinel
    everywhere. Does nothing in a process that multiprocessing did not start."""
    parent = multiprocessing.parent_process()
    if parent is None or parent.pid is None:
        return
    ask_for_death_signal(signal.SIGKILL, parent.pid)

    def watch():
        multiprocessing.connection.wait([parent.sentinel])
        os._exit(1)

    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def run_pickled(payload: bytes, *extra) -> None:
    """Entry of a spawned worker: first die with the parent, then unpickle ``payload``
    (a function and its arguments, whose modules are imported only now) and call it as
    ``function(*arguments, *extra)``. ``extra`` carries what can only travel by
    inheritance, such as a pipe's end."""
    die_with_parent()
    function, arguments = pickle.loads(payload)
    function(*arguments, *extra)


def compiler_preexec(parent_pid: int):
    """A ``preexec_fn`` for a compiler's shell wrapper: SIGTERM when the parent ends."""
    return lambda: ask_for_death_signal(signal.SIGTERM, parent_pid)


#: Runs ``"$@"`` (the compiler command) in the background and waits for it; SIGTERM (sent
#: by the kernel when the Python parent ends) kills the whole process group, so that the
#: compiler's own children (cc1, as, collect2) end with it too.
GROUP_WRAPPER = 'trap "kill -KILL 0" TERM; "$@" & wait $!'


def in_own_group(command: list[str]) -> list[str]:
    """``command`` run through :data:`GROUP_WRAPPER` by ``sh``."""
    return ["sh", "-c", GROUP_WRAPPER, "baslip-compiler", *command]
