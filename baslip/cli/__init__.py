"""The command line: thin layers over the Python verbs (``baslip``, ``python -m
baslip.solve``, ...).

A command's process, and the study workers it starts, run OpenBLAS (numpy's and
CasADi's) on one thread unless ``OPENBLAS_NUM_THREADS`` says otherwise. baslip's linear
algebra is on matrices of 4 x 4 to a few hundred rows, too small for BLAS threads to
share; starting them and their spinning cost 0.12 s of CPU in every process (measured on
``import numpy, casadi``: 0.25 s against 0.13 s), a third of a warm gait's whole run, and
two workers' threads would contend for the same two cores. The variable is read when the
libraries load, so it is set here, before anything imports them; the Python verbs leave an
application's own process as it is.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def main(argv: list[str] | None = None) -> int:
    """The ``baslip`` command; kept here too, so that a console script installed before
    the command moved to :mod:`baslip.cli.main` still runs."""
    from baslip.cli.main import main as command

    return command(argv)
