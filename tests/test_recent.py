"""Specification of baslip.engine.recent: the engine remembers its last few settled
strides, so that a Jacobian taken where a value was just taken settles the stride once,
and its last few Jacobians, so that a second Jacobian at the same point is not taken
again; with the very numbers a fresh engine computes, and no caller can change another's."""

import numpy as np

from baslip import Params, ReturnMap, Tolerances
from baslip.engine.outcome import Stride
from baslip.engine.recent import MISSING, RECENT_STRIDES, RecentAnswers, settle_key

PARAMS = Params()
X_GAIT = np.array([0.4, -1.5657, 0.5, 0.164274])  # near the shipped downward gait
U_GAIT = np.array([-0.751879, 1.50002, -0.05246, 1.42038, 0.11471])


def key(i: int) -> bytes:
    return settle_key(np.full(4, float(i)), np.zeros(5), np.ones(6), 0.2)


def test_an_entry_comes_back_as_a_copy_the_caller_cannot_change_for_others():
    recent = RecentAnswers()
    stride = Stride(np.array([0.4, 0.1, 0.5, 0.2]), {"descent": 0.2})
    recent.put(key(0), (24, stride, np.array([0.2, 0.05, 0.05])))
    first = recent.get(key(0))
    first[1].apex[0] = -1.0
    first[1].durations["descent"] = -1.0
    first[2][0] = -1.0
    stride.apex[1] = -1.0  # the caller's own object, changed after it was remembered
    again = recent.get(key(0))
    assert again[0] == 24
    assert np.array_equal(again[1].apex, [0.4, 0.1, 0.5, 0.2]) and again[1].durations == {"descent": 0.2}
    assert np.array_equal(again[2], [0.2, 0.05, 0.05])


def test_a_jacobian_entry_comes_back_as_a_copy_too():
    recent = RecentAnswers()
    jacobian = np.arange(60.0).reshape(4, 15)
    recent.put(key(0), (jacobian, Stride(np.array([0.4, 0.1, 0.5, 0.2]), {"descent": 0.2})))
    recent.get(key(0))[0][0, 0] = -1.0
    jacobian[0, 1] = -1.0
    again = recent.get(key(0))
    assert np.array_equal(again[0], np.arange(60.0).reshape(4, 15)) and again[1].apex[0] == 0.4


def test_an_answer_is_computed_once_and_handed_out_as_copies():
    recent, computed = RecentAnswers(), []

    def compute():
        computed.append(1)
        return np.array([1.0, 2.0])

    first = recent.answer(key(0), compute)
    first[0] = -1.0
    assert np.array_equal(recent.answer(key(0), compute), [1.0, 2.0]) and computed == [1]


def test_none_is_an_answer_and_missing_is_not():
    recent = RecentAnswers()
    recent.put(key(0), None)
    assert recent.get(key(0)) is None
    assert recent.get(key(1)) is MISSING


def test_the_oldest_entry_is_forgotten_first():
    recent = RecentAnswers()
    for i in range(RECENT_STRIDES + 1):
        recent.put(key(i), i)
    assert recent.get(key(0)) is MISSING
    assert [recent.get(key(i)) for i in range(1, RECENT_STRIDES + 1)] == list(range(1, RECENT_STRIDES + 1))


def test_the_key_tells_apart_strides_that_differ_in_the_last_bit():
    X = X_GAIT.copy()
    nudged = X.copy()
    nudged[3] = np.nextafter(nudged[3], 1.0)
    assert settle_key(X, U_GAIT, PARAMS.vector(), 0.2) != settle_key(nudged, U_GAIT, PARAMS.vector(), 0.2)
    assert settle_key(X, U_GAIT, PARAMS.vector(), 0.2) != settle_key(X, U_GAIT, PARAMS.vector(), np.nextafter(0.2, 1))


def counted(kernel: str) -> tuple[ReturnMap, ReturnMap, list[int]]:
    """A map whose engine lists the step counts of each ``kernel`` it takes, and a fresh one."""
    rmap, fresh = ReturnMap(Tolerances(1e-12, 1e-12)), ReturnMap(Tolerances(1e-12, 1e-12))
    functions, taken = rmap.compiled_engine.functions, []
    original = getattr(functions, kernel)
    setattr(functions, kernel, lambda n: taken.append(n) or original(n))
    return rmap, fresh, taken


def test_a_jacobian_after_a_value_at_the_same_point_settles_once_with_a_fresh_engines_numbers():
    rmap, fresh, passes = counted("final")
    value = rmap.stride(X_GAIT, U_GAIT, PARAMS)
    settled = len(passes)
    A, B = rmap.jacobians(X_GAIT, U_GAIT, PARAMS)
    assert settled > 0 and len(passes) == settled  # no value pass again for the Jacobian
    A_fresh, B_fresh = fresh.jacobians(X_GAIT, U_GAIT, PARAMS)
    assert np.array_equal(A, A_fresh) and np.array_equal(B, B_fresh)
    assert np.array_equal(value.apex, fresh.stride(X_GAIT, U_GAIT, PARAMS).apex)


def test_a_second_jacobian_at_the_same_point_is_not_taken_again_and_is_a_fresh_engines():
    rmap, fresh, taken = counted("jacobian")
    A, B = rmap.jacobians(X_GAIT, U_GAIT, PARAMS)
    A[0, 0] = np.nan  # the caller's copy: the next caller's numbers stay the engine's
    A_again, B_again = rmap.jacobians(X_GAIT, U_GAIT, PARAMS)
    assert len(taken) == 1
    A_fresh, B_fresh = fresh.jacobians(X_GAIT, U_GAIT, PARAMS)
    assert np.array_equal(A_again, A_fresh) and np.array_equal(B_again, B_fresh)
    nudged = X_GAIT + np.array([0.0, 0.0, 0.0, 1e-12])
    rmap.jacobians(nudged, U_GAIT, PARAMS)
    assert len(taken) == 2  # another point: taken afresh
