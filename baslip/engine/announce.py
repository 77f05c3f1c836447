"""What a compile says while gcc runs: the library's name, its size and about how long it
takes (estimated from the size), then every few seconds that it still runs. A first run
compiles for minutes; without this its silence would look like a hang.
"""

from __future__ import annotations

import contextlib
import logging
import pathlib
from collections.abc import Iterator

from baslip.diagnostics import heartbeat

#: Generated C from which on a build is announced (smaller ones take a second or two).
ANNOUNCE_BYTES = 200_000
#: gcc's time for a library of 1 MB of C by optimisation level, on the 2-core machine [s],
#: and the power of the size it grows with (superlinearly: large functions cost the
#: optimiser more per line). Fitted to compiles of baslip's libraries there: at -O3
#: 0.25 MB in 2.3 s and 0.64 MB in 10.1 s (and the 4 MB stability NLP in about 180 s), at
#: -O1 1.1 MB in 5.6 s and 2.84 MB in 30 s, at -O0 (a one-gait run's return maps) one
#: step count's Jacobian, 1.16 MB in 2.0 s.
SECONDS_PER_MB = {"-O3": 20.6, "-O1": 5.7, "-O0": 1.6}
SIZE_POWER = 1.6


def expected_compile_s(size: int, optimisation: str = "-O3") -> float:
    """About how long gcc takes for ``size`` bytes of generated C at ``optimisation`` [s]."""
    return SECONDS_PER_MB.get(optimisation, SECONDS_PER_MB["-O3"]) * (size / 1e6) ** SIZE_POWER


@contextlib.contextmanager
def announced(log: logging.Logger, name: str, c_text: str, folder: pathlib.Path,
              optimisation: str = "-O3") -> Iterator[None]:
    """Say on ``log`` (the compiling module's) that ``name`` is being compiled into a
    library in ``folder``, its size and about how long it takes at ``optimisation``, then
    while the block runs say every few seconds that it still is (:func:`~baslip.diagnostics.heartbeat`):
    the silence of a first run would otherwise look like a hang. Small libraries get
    nothing. (A study's worker sends these lines to its parent's progress line.)"""
    size = len(c_text.encode())
    if size < ANNOUNCE_BYTES:
        yield
        return
    expected = expected_compile_s(size, optimisation)
    log.info(f"baslip: compiling {name} for this machine ({size / 1e6:.1f} MB of C, about {expected:.0f} s; "
             f"once, then kept in {folder})")

    def still(elapsed: float) -> str:
        if elapsed <= expected:
            return f"baslip: still compiling {name}, {elapsed:.0f} s of about {expected:.0f} s"
        return f"baslip: still compiling {name}, {elapsed:.0f} s (about {expected:.0f} s was expected)"

    with heartbeat(log, still):
        yield
