"""Which matplotlib backend baslip draws with, and who shows its figures.

baslip draws off-screen (Agg) so that a command-line run, a worker or a headless machine
never opens a window. In a Jupyter kernel, which asks for its inline backend through
``MPLBACKEND=module://...``, it keeps that backend instead: importing baslip must not
switch off the notebook's own figures. There a figure baslip returns is left to pyplot,
which shows it at the end of the cell like any other (so ``fig = result.plot()`` followed
by more lines shows it too); elsewhere it is let go of by pyplot at once, so that a
script that draws many does not accumulate them.
"""

from __future__ import annotations

import os

import matplotlib

#: How Jupyter kernels name their (inline or widget) backends in ``MPLBACKEND``.
NOTEBOOK_BACKENDS = "module://"


def in_notebook() -> bool:
    """Whether matplotlib was asked for a notebook's backend (inline or widget)."""
    return os.environ.get("MPLBACKEND", "").startswith(NOTEBOOK_BACKENDS)


def use_file_backend() -> None:
    """Draw off-screen (Agg), unless a notebook's backend was asked for."""
    if not in_notebook():
        matplotlib.use("Agg")


def hand_over(figure) -> None:
    """Give a figure to the caller: pyplot shows it at the end of a notebook cell; outside
    a notebook pyplot forgets it (the Figure stays usable: draw, save, show in a page)."""
    if not in_notebook():
        release(figure)


def release(figure) -> None:
    """Let pyplot forget ``figure`` (it then never shows it by itself)."""
    import matplotlib.pyplot as plt  # after the backend is chosen: importing pyplot fixes it

    plt.close(figure)
