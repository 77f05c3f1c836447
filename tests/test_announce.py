"""Specification of baslip.engine.announce: a compile's estimate of its time. (That a
compile is announced and heard from while gcc runs is in test_compile.py, with the build.)"""

import pytest

from baslip.engine.announce import expected_compile_s


def test_the_expected_compile_time_follows_the_measured_ones():
    """The estimate is within 30 % of the compiles it was fitted to (size [MB], level, s)."""
    for megabytes, level, seconds in ((0.25, "-O3", 2.3), (0.64, "-O3", 10.1), (1.1, "-O1", 5.6), (2.84, "-O1", 30.0)):
        assert expected_compile_s(int(megabytes * 1e6), level) == pytest.approx(seconds, rel=0.3)
