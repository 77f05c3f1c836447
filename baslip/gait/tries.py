"""IPOPT's tries, told as they run: a try after the first is announced as it starts (with
how the one before ended), and any try that runs long is heard from every few seconds
(:func:`baslip.diagnostics.heartbeat`), so that a slow solve never looks like a hang.

The tries' outcomes, for the record, are the solver report's business; this module only
speaks while they run.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

from baslip.diagnostics import heartbeat, logger

_log = logger(__name__)


@dataclass(frozen=True)
class IpoptAttempt:
    """One IPOPT try of a solve.

    Attributes
    ----------
    number : int
        Its place among the tries, from 1.
    most : int
        How many tries the solve may make (a second one only after a failure).
    what : str
        What this try solves with ("limited-memory Hessian", say).
    after : str
        How the try before it ended ("" for the first).
    """

    number: int = 1
    most: int = 1
    what: str = ""
    after: str = ""

    def name(self) -> str:
        """``IPOPT try 2 of 2 (exact Hessian)``; ``of up to`` while more tries may follow."""
        most = f"up to {self.most}" if self.number < self.most else str(self.most)
        return f"IPOPT try {self.number} of {most}" + (f" ({self.what})" if self.what else "")


@contextlib.contextmanager
def told(attempt: IpoptAttempt) -> Iterator[None]:
    """Announce ``attempt`` if it is not the first, and say every few seconds that it
    still runs while the block does."""
    if attempt.number > 1:
        _log.info(f"{attempt.name()}: starting from the same start; try {attempt.number - 1} ended {attempt.after}")
    with heartbeat(_log, lambda elapsed: f"{attempt.name()}: still solving, {elapsed:.0f} s"):
        yield


def first_try(hessian: str) -> IpoptAttempt:
    """The first try of a shooting NLP whose Hessian is ``hessian``: an exact-Hessian
    second try may follow unless it is exact already."""
    return IpoptAttempt(1, 1 if hessian == "exact" else 2, f"{hessian} Hessian")


def ended(solution) -> str:
    """How a try ended, from its :class:`~baslip.gait.shooting.NlpSolution`: IPOPT's
    status and iterations."""
    return f"{solution.return_status} after {solution.iterations} iterations"
