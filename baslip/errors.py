"""The two roots of what baslip raises: bad input, and runs that did not succeed.

* :class:`InputError`: the input cannot be run as given (a problem file, a changed
  problem, an option, a file a run reads, an output folder). It carries the dotted
  ``key`` of the offending entry (empty when no key names it) and a one-line message.
  The command line catches this class once and exits with status 2.
* :class:`RunError`: the input was fine, but a solver or a run did not succeed (a
  start that did not converge, a worker that died). The command line exits with 1.

This module imports nothing, so every layer can raise these.
"""

from __future__ import annotations


class InputError(ValueError):
    """Input baslip refuses; ``key`` is the dotted path of the offending entry, or ``""``.

    Parameters
    ----------
    key : str
        The dotted key (``params.m``, ``study.boundary``, ``--scheduler``), or ``""``.
    message : str
        What is wrong with it, one line.
    """

    def __init__(self, key: str, message: str):
        text = f"{key}: {message}" if key else message
        # One line, whatever the file contained (keys or values may hold newlines).
        super().__init__(text.replace("\r", "\\r").replace("\n", "\\n"))
        self.key, self.message = key, message


class ProblemError(InputError):
    """An invalid problem; ``key`` is the dotted path of the offending entry."""


class ProblemKindError(InputError):
    """A verb was given a problem of a kind it does not run (a study to ``solve_problem``)."""


class RunError(RuntimeError):
    """A solver or run that did not succeed on valid input."""


class ArgumentError(InputError):
    """A bad argument to a public Python function (a shape, type, range or size);
    ``key`` names the argument."""
