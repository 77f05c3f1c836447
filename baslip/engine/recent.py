"""A bounded memo of an engine's recent answers: its settled strides, and its Jacobians.

Every Newton, Gauss-Newton and Levenberg-Marquardt loop over the return map evaluates a
point and then differentiates it there: the polish, the atlas's corrector, the descents,
the re-solving controllers. The compiled engine's Jacobian starts with the same value
passes that settled the stride's step count, so without a memo that work is done twice.
Some callers also take the Jacobian at one point twice: the stability descent, for the
multipliers of a trial point and then for the fixed-point equations there. The passes are
deterministic, so an answer taken from a memo is the one the engine would compute again,
bit for bit; what it hands out is a copy, so that no caller can change another's numbers.
Like its kernels' work memory, an engine's memos serve one thread at a time (each lane of
a batch has an engine of its own).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from baslip.engine.outcome import Stride

#: Strides remembered: a receding horizon of N strides evaluates N of them before it
#: differentiates the first, and rejected trial plans come in between.
RECENT_STRIDES = 8
#: What :meth:`RecentAnswers.get` returns for a stride it does not hold (None is an answer).
MISSING = object()


def settle_key(X: np.ndarray, u: np.ndarray, p: np.ndarray, t_guess: float) -> bytes:
    """The exact inputs of a stride, as one key: apex, controls, parameters and the
    touchdown time guess [s] the engine starts from."""
    return np.concatenate([X, u, p, [t_guess]]).astype(float).tobytes()


class RecentAnswers:
    """The engine's answers for its last :data:`RECENT_STRIDES` strides, oldest forgotten first.

    An entry is whatever the engine returned: for its settling, a fall found in planning
    (a :class:`Stride`), None, or (step count, verdict, event guesses); for its
    Jacobians, None or (Jacobian, stride).

    Parameters
    ----------
    size : int
        Strides remembered, at least 1.
    """

    def __init__(self, size: int = RECENT_STRIDES):
        if size < 1:
            raise ValueError(f"a memo remembers at least 1 stride, not {size}")
        self.size = size
        self._entries: dict[bytes, object] = {}

    def get(self, key: bytes) -> object:
        """A copy of the entry for ``key``, or :data:`MISSING`."""
        entry = self._entries.get(key, MISSING)
        return entry if entry is MISSING else _copied(entry)

    def answer(self, key: bytes, compute: Callable[[], object]) -> object:
        """A copy of the entry for ``key``; where there is none, ``compute()``'s answer,
        remembered."""
        entry = self.get(key)
        if entry is MISSING:
            entry = compute()
            self.put(key, entry)
        return entry

    def put(self, key: bytes, answer: object) -> None:
        """Remember a copy of ``answer`` under ``key``, forgetting the oldest entry if full."""
        self._entries.pop(key, None)
        if len(self._entries) >= self.size:
            del self._entries[next(iter(self._entries))]
        self._entries[key] = _copied(answer)


def _copied(answer: object) -> object:
    """A copy of an answer whose arrays and durations are its own."""
    if isinstance(answer, Stride):
        return replace(answer, apex=None if answer.apex is None else answer.apex.copy(),
                       durations=dict(answer.durations))
    if isinstance(answer, np.ndarray):
        return answer.copy()
    if isinstance(answer, tuple):
        return tuple(_copied(part) for part in answer)
    return answer
