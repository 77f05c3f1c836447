"""What became of a solve: an enumeration, written to JSON and CSV as its plain string."""

from __future__ import annotations

import enum

#: A fixed point is reported only if the independent re-simulation gives eps below this.
VERIFY_EPS = 1e-10


class Status(enum.StrEnum):
    """The outcome of a fixed-point solve.

    A member is a ``str`` (``Status.CONVERGED == "converged"``), so it is written to
    ``result.json`` and CSV files as before; :attr:`message` says what it means.
    """

    CONVERGED = "converged"
    NOT_VERIFIED = "not_verified"
    FAILED = "failed"

    @property
    def message(self) -> str:
        """One line saying what the status means."""
        return _MESSAGES[self]

    @property
    def ok(self) -> bool:
        """Whether the result is a verified fixed point."""
        return self is Status.CONVERGED


_MESSAGES = {
    Status.CONVERGED: "a fixed point, confirmed by an independent tight-tolerance re-simulation",
    Status.NOT_VERIFIED: "the solver stopped at a point the independent re-simulation does not confirm",
    Status.FAILED: "the solver failed (IPOPT's return status says why)",
}
