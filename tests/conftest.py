"""Shared, session-wide fixtures: CasADi objects are built once and reused."""

import numpy as np
import pytest

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
