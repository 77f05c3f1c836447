"""Shared, session-wide fixtures: CasADi objects are built once and reused."""

import ast
import contextlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fakeclock import clock_in_place

from baslip import FixedPointSolver, Params, ReturnMap, Tolerances


@pytest.fixture(scope="session")
def params():
    return Params()


@pytest.fixture(scope="session")
def tight_map():
    """Return map at rtol = atol = 1e-12."""
    return ReturnMap(Tolerances(1e-12, 1e-12))


@pytest.fixture(scope="session")
def solver():
    return FixedPointSolver()


@pytest.fixture
def running_point():
    """A downward running apex X and control u that take a clean stride (not a fixed point)."""
    return np.array([0.4, -np.pi / 2 + 0.02, 0.5, 0.1]), np.array([0.1, 0.01, 0.2, 0.0, 0.15])


#: Modules a single gait's run should not import: the studies', their workers' and matplotlib.
HEAVY_MODULES = ("matplotlib", "baslip.studies.registry", "baslip.studies.branch", "baslip.viz.figures",
                 "baslip.studies.runner", "multiprocessing")


@pytest.fixture(scope="session")
def heavy_modules_after():
    """``heavy_modules_after(statement)``: run the Python ``statement`` (which sets
    ``result``) in a fresh interpreter at the repository's root; (``result``'s text, the
    :data:`HEAVY_MODULES` it left imported, sorted), with its output on failure."""
    root = Path(__file__).resolve().parents[1]

    def run(statement: str) -> tuple[str, list[str]]:
        script = (f"import sys\n{statement}\n"
                  f"print(result, sorted(m for m in {HEAVY_MODULES!r} if m in sys.modules))")
        proc = subprocess.run([sys.executable, "-c", script], cwd=root, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        text, modules = proc.stdout.split("\n")[-2].split(" ", 1)
        return text, ast.literal_eval(modules)

    return run


@pytest.fixture
def fake_clock():
    """``fake_clock(shown=True)``: a :class:`fakeclock.FakeClock` in place of baslip's
    clock until the test ends, hearing baslip's records (INFO shown, or with ``shown``
    False only warnings, as with ``--quiet``); a second call replaces the first."""
    with contextlib.ExitStack() as stack:
        yield lambda shown=True: (stack.close(), stack.enter_context(clock_in_place(shown)))[1]
