"""A library compiled in a thread while the process goes on: the kernels it gives are the
virtual machine's numbers, whether compiled, loaded from the cache or fallen back to; the
caller is not held up by gcc; the optimisation level is part of the library's key."""

import pathlib
import time

import casadi as ca
import numpy as np
import pytest

from baslip.engine import codegen
from baslip.engine.background import KernelsLater
from baslip.engine.native import NativeKernel, VirtualMachineKernel

POINT = np.array([0.3, -0.2, 0.7])


def _functions():
    x = ca.SX.sym("x", 3)
    step = ca.Function("step", [x], [x + 0.01 * ca.vertcat(ca.sin(x[1]), ca.cos(x[0]) * x[2], x[0] * x[1])])
    end = step.mapaccum("steps", 40)(x)[:, -1]
    return [ca.Function("f", [x], [end]), ca.Function("f_jac", [x], [ca.jacobian(end, x)])]


def _values(kernels):
    return [np.asarray(kernels[f.name()](POINT)[0]) for f in _functions()]


def _reference():
    return [np.asarray(f(POINT)).ravel() for f in _functions()]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("BASLIP_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("BASLIP_NO_COMPILE", raising=False)
    monkeypatch.delenv("CC", raising=False)
    return tmp_path / "cache"


def _later(optimisation="-O1"):
    return KernelsLater("test_later", ["f", "f_jac"], _functions, [pathlib.Path(__file__)],
                        optimisation=optimisation)


def test_the_caller_goes_on_while_gcc_runs_and_then_gets_the_compiled_numbers(cache, monkeypatch):
    started, finished = [], []
    build = codegen._build

    def slow_build(*arguments):  # a compile that takes a while, as the engine's does
        started.append(time.monotonic())
        time.sleep(1.0)
        build(*arguments)
        finished.append(time.monotonic())

    monkeypatch.setattr(codegen, "_build", slow_build)
    later = _later()
    handed_back = time.monotonic()
    kernels = later.get()
    assert started and finished and handed_back < finished[0]  # not held up by the compile
    assert all(isinstance(k, NativeKernel) for k in kernels.values())
    for got, want in zip(_values(kernels), _reference()):
        np.testing.assert_allclose(got.ravel(), want, rtol=1e-15, atol=0)


def test_a_second_one_loads_the_cached_library_without_a_thread(cache):
    _later().get()
    again = _later()
    assert again._thread is None  # loaded at once
    assert all(isinstance(k, NativeKernel) for k in again.get().values())


def test_each_optimisation_level_is_its_own_library_with_the_same_numbers(cache):
    low, high = _later("-O1").get(), _later("-O3").get()
    assert len(list(cache.glob("test_later-*.so"))) == 2
    for a, b in zip(_values(low), _values(high)):
        np.testing.assert_array_equal(a, b)  # no fast-math, no contraction: bit for bit


def test_without_a_compiler_the_virtual_machine_serves(cache, monkeypatch):
    monkeypatch.setattr(codegen._PROCESS, "noticed", set())  # its notice is this test's own, once per process
    monkeypatch.setenv("CC", "false")
    kernels = _later().get()
    assert all(isinstance(k, VirtualMachineKernel) for k in kernels.values())
    for got, want in zip(_values(kernels), _reference()):
        np.testing.assert_allclose(got.ravel(), want, rtol=1e-15, atol=0)


def test_with_compiling_switched_off_there_is_no_thread_and_the_caller_builds_what_it_uses(cache, monkeypatch):
    monkeypatch.setenv("BASLIP_NO_COMPILE", "1")
    built = []
    later = KernelsLater("test_later", ["f", "f_jac"], lambda: built.append(1) or _functions(),
                         [pathlib.Path(__file__)])
    assert later._thread is None and not cache.exists()
    assert later.get() is None and built == []  # nothing built for functions the caller may never use


def test_a_library_of_few_calls_compiles_quickly_unless_its_tuned_copy_is_cached(cache, monkeypatch):
    """FEW_CALLS (a one-gait run): gcc's quickest level when the cache lacks the library, with
    the same numbers to the bit; the library at its own level once the cache holds it."""
    built, loaded = [], []
    build, native = codegen._build, codegen._native_kernels
    monkeypatch.setattr(codegen, "_build", lambda *a: (built.append((a[3].name, a[4])), build(*a))[1])
    monkeypatch.setattr(codegen, "_native_kernels", lambda library, names: (loaded.append(library.name),
                                                                            native(library, names))[1])

    def few_calls():
        return KernelsLater("test_later", ["f", "f_jac"], _functions, [pathlib.Path(__file__)], optimisation="-O1",
                            enabled=codegen.FEW_CALLS)

    quick = few_calls().get()
    assert [level for _, level in built] == [codegen.QUICK_OPTIMISATION]
    tuned = _later("-O1").get()
    assert [level for _, level in built] == [codegen.QUICK_OPTIMISATION, "-O1"]
    for a, b in zip(_values(quick), _values(tuned)):
        np.testing.assert_array_equal(a, b)
    again = few_calls()
    assert again._thread is None and len(built) == 2  # loaded, nothing compiled
    assert loaded[-1] == built[1][0]  # the tuned library
