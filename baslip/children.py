"""Child processes that end with the process that started them, however it ends.

Two kinds of children are started by baslip: the worker processes of a study and the C
compiler. Both must die with their parent, even when the parent is killed with SIGKILL
and so runs no clean-up of its own. On Linux the kernel does it: a process can ask for a
signal when its parent ends (``PR_SET_PDEATHSIG``). The request must come first, before
anything slow, and the parent checked once more after it, because a parent that ended
before the request was made sends no signal. Everywhere, a worker also watches its
standard input, which its parent holds open and which reaches its end when the parent dies.

A worker starts from baslip's own entry point, :data:`WORKER_BOOTSTRAP`, never from the
caller's ``__main__``, so a script without an ``if __name__ == "__main__":`` guard,
``python -c``, standard input and notebooks all start workers alike. This module imports
nothing heavy on purpose: a worker imports it first (:func:`serve_worker`), sets the
request, and only then unpickles and imports the work it was given.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import pickle
import signal
import sys
import threading
from multiprocessing.connection import Connection

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


#: The environment variable that marks a worker: the pid of the process that started it.
#: It lets a test (or a user) find a run's workers, even once their parent has gone.
WORKER_OF = "BASLIP_WORKER_OF"

#: The program a worker runs (``python -c``). It ignores Ctrl-C (the parent stops its
#: workers itself), reads its start (:func:`worker_start`) from standard input, takes the
#: parent's ``sys.path`` so that it imports what the parent imports, and hands over to
#: :func:`serve_worker`. A parent that dies before sending the start ends it quietly.
WORKER_BOOTSTRAP = """\
import pickle, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
try:
    start = pickle.load(sys.stdin.buffer)
except EOFError:
    sys.exit(1)
sys.path[:] = start["path"]
from baslip.children import serve_worker
serve_worker(start)
"""


def worker_start(payload: bytes, end: Connection) -> dict:
    """What a worker is sent on its standard input: this process's pid and ``sys.path``,
    the descriptor of its end of the pipe ``end`` (inherited), and ``payload``: a
    function and its arguments, pickled. Only plain data, so that unpickling it imports
    nothing."""
    return {"parent": os.getpid(), "path": list(sys.path), "fd": end.fileno(), "readable": end.readable,
            "writable": end.writable, "work": payload}


def serve_worker(start: dict) -> None:
    """Entry of a worker process (after :data:`WORKER_BOOTSTRAP`): first die with the
    parent, then unpickle the work (whose modules are imported only now) and call it as
    ``function(*arguments, connection)``, ``connection`` being the worker's end of its pipe."""
    ask_for_death_signal(signal.SIGKILL, start["parent"])
    threading.Thread(target=_end_when_parent_ends, name="die-with-parent", daemon=True).start()
    connection = Connection(start["fd"], readable=start["readable"], writable=start["writable"])
    function, arguments = pickle.loads(start["work"])
    function(*arguments, connection)


def _end_when_parent_ends() -> None:
    """Read standard input to its end, which comes when the parent closes it or dies, then
    end this process. (The descriptor is read raw: a daemon thread blocked inside
    ``sys.stdin`` would hold its lock when the interpreter shuts down.)"""
    while os.read(sys.stdin.fileno(), 4096):
        pass
    os._exit(1)


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
