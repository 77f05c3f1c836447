"""Compiling CasADi Functions to C: same numbers as the VM, a disk cache, safe fallbacks.

Every test uses its own cache directory (``BASLIP_CACHE_DIR`` under ``tmp_path``), so
none touches the user's cache; the compiler is gcc unless a test sets ``CC``.
"""

import hashlib
import logging
import os
import pathlib
import shutil
import subprocess
import sys
import textwrap
import time

import casadi as ca
import numpy as np
import pytest

from baslip.engine.codegen import cache_dir, compile_functions

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")

POINTS = [np.array([0.3, -0.2, 0.5]), np.array([-1.1, 2.0, 0.25]), np.zeros(3)]



@pytest.fixture(autouse=True)
def _diagnostics_recorded(caplog):
    caplog.set_level(logging.INFO, logger="baslip")


def _said(caplog) -> list[str]:
    """The diagnostics the compiler's module logged since the last call (they go through
    logging: the command line shows them on stderr)."""
    lines = [r.getMessage() for r in caplog.records if r.name == "baslip.engine.codegen"]
    caplog.clear()
    return lines

def make_functions(gain=0.01):
    """A map f(x) = 30 steps of an SX step function (sin, cos) via mapaccum, and its Jacobian."""
    x = ca.SX.sym("x", 3)
    step = ca.Function(
        "step", [x], [x + gain * ca.vertcat(ca.sin(x[1]), ca.cos(x[0]) * x[2], x[0] * x[1])]
    )
    trajectory = step.mapaccum("steps", 30)(x)
    f = ca.Function("f", [x], [trajectory[:, -1], ca.sumsqr(trajectory)])
    f_jac = ca.Function("f_jac", [x], [ca.jacobian(f(x)[0], x)])
    return [f, f_jac]


def assert_same_results(functions, results):
    """``results`` (name -> Function) give the numbers of ``functions`` to 1e-15 relative."""
    assert sorted(results) == sorted(f.name() for f in functions)
    for f in functions:
        for point in POINTS:
            for got, want in zip(results[f.name()].call([point]), f.call([point])):
                np.testing.assert_allclose(np.array(got), np.array(want), rtol=1e-15, atol=0)


def libraries(directory):
    return sorted(p.name for p in directory.iterdir() if p.name.endswith(".so"))


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache directory of this test's own, with compiling switched on."""
    directory = tmp_path / "cache"
    monkeypatch.setenv("BASLIP_CACHE_DIR", str(directory))
    monkeypatch.delenv("BASLIP_NO_COMPILE", raising=False)
    monkeypatch.delenv("CC", raising=False)
    return directory


def test_cache_dir_from_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("BASLIP_CACHE_DIR", str(tmp_path / "a"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "a"
    monkeypatch.delenv("BASLIP_CACHE_DIR")
    assert cache_dir() == tmp_path / "xdg" / "baslip"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "baslip"


def test_compiled_functions_match_the_virtual_machine(cache, caplog):
    functions = make_functions()
    compiled = compile_functions("test_lib", functions)
    assert all(g.is_a("External") for g in compiled.values())
    assert_same_results(functions, compiled)
    assert libraries(cache) == [next(iter(libraries(cache)))]  # one library for both
    assert libraries(cache)[0].startswith("test_lib-")
    assert _said(caplog) == []


def test_second_call_loads_from_the_cache_without_compiling(cache, tmp_path, monkeypatch, caplog):
    """The compiler is asked for its version (part of the key) once per process, and the
    second call does not run it at all."""
    log = tmp_path / "cc.log"
    wrapper = tmp_path / "cc"
    wrapper.write_text(f'#!/bin/sh\necho "$@" >> {log}\nexec gcc "$@"\n')
    wrapper.chmod(0o755)
    monkeypatch.setenv("CC", str(wrapper))
    functions = make_functions()
    compile_functions("test_lib", functions)
    [library] = cache.glob("*.so")
    mtime = library.stat().st_mtime_ns
    assert sum("-shared" in line for line in log.read_text().splitlines()) == 1

    assert log.read_text().splitlines().count("--version") == 1
    log.unlink()
    again = compile_functions("test_lib", make_functions())  # rebuilt, equal Functions
    assert not log.exists()
    assert library.stat().st_mtime_ns == mtime
    assert libraries(cache) == [library.name]
    assert_same_results(functions, again)
    assert _said(caplog) == []


def test_a_large_build_says_what_it_compiles_and_about_how_long_a_cached_load_says_nothing(cache, monkeypatch,
                                                                                           caplog):
    """Above ANNOUNCE_BYTES of C (lowered here, so that a small library counts), a build
    logs one line naming the library, its size and an estimate, in a log as on a
    terminal; the load from the cache logs none. Below the size a build is silent."""
    import baslip.engine.announce as announce

    compile_functions("test_lib_small", make_functions(gain=0.03))
    assert _said(caplog) == []
    monkeypatch.setattr(announce, "ANNOUNCE_BYTES", 1)
    for terminal, name in ((False, "test_lib_piped"), (True, "test_lib")):
        monkeypatch.setattr(sys.stderr, "isatty", lambda terminal=terminal: terminal)
        compile_functions(name, make_functions())
        [line] = _said(caplog)
        assert line.startswith(f"baslip: compiling {name} for this machine (") and " MB of C, about " in line
        assert str(cache) in line
    compile_functions("test_lib", make_functions())
    assert _said(caplog) == []


def test_a_long_compile_is_never_silent_for_more_than_10_s_and_quiet_silences_it(cache, monkeypatch, fake_clock):
    """A gcc that takes 47 s (a stub moving a fake clock, then the real gcc) is announced
    and then heard from at least every 10 s, past its estimate too; with INFO not shown
    (``progress=False``, ``--quiet``) nothing is said and no heartbeat runs."""
    import baslip.engine.announce as announce
    import baslip.engine.codegen as codegen
    from baslip import diagnostics

    real_run = codegen._run
    monkeypatch.setattr(announce, "ANNOUNCE_BYTES", 1)
    monkeypatch.setattr(announce, "expected_compile_s", lambda size, optimisation: 30.0)
    clock = fake_clock()

    def slow_gcc(command):
        if "-shared" in command:
            diagnostics.CLOCK.advance(47.0)
        return real_run(command)

    monkeypatch.setattr(codegen, "_run", slow_gcc)
    compile_functions("test_lib", make_functions())
    said = clock.messages()
    assert said[0].startswith("baslip: compiling test_lib for this machine (") and "about 30 s" in said[0]
    assert "baslip: still compiling test_lib, 18 s of about 30 s" in said
    assert said[-1] == "baslip: still compiling test_lib, 45 s (about 30 s was expected)"
    assert clock.longest_silence() <= 10.0 and clock.running() == 0

    quiet = fake_clock(shown=False)
    compile_functions("test_lib", make_functions(gain=0.02))
    assert quiet.said == [] and quiet.time == 47.0 and quiet.running() == 0


def test_the_compiler_version_is_asked_without_a_shell(cache, tmp_path, monkeypatch):
    """The probe runs the compiler itself (no ``sh -c`` wrapper), once per process."""
    import baslip.engine.codegen as codegen

    commands = []
    run = subprocess.run
    monkeypatch.setattr(codegen.subprocess, "run", lambda command, **kw: (commands.append(command), run(command, **kw))[1])
    wrapper = tmp_path / "cc"
    wrapper.write_text('#!/bin/sh\nexec gcc "$@"\n')
    wrapper.chmod(0o755)
    monkeypatch.setenv("CC", str(wrapper))
    compile_functions("test_lib", make_functions())
    compile_functions("test_lib", make_functions(0.02))
    assert commands == [[str(wrapper), "--version"]]


def test_changed_function_gets_its_own_library(cache):
    compile_functions("test_lib", make_functions(0.01))
    first = libraries(cache)
    compiled = compile_functions("test_lib", make_functions(0.02))
    assert len(first) == 1 and len(libraries(cache)) == 2
    assert_same_results(make_functions(0.02), compiled)


def test_without_a_compiler_the_originals_are_used_with_one_notice(cache, monkeypatch, caplog):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    functions = make_functions()
    result = compile_functions("test_lib", functions)
    assert all(result[f.name()] is f for f in functions)
    lines = _said(caplog)
    assert len(lines) == 1
    assert lines[0].startswith("baslip: no working C compiler (")
    assert "virtual machine" in lines[0]
    assert not cache.exists() or list(cache.iterdir()) == []


def test_failing_compiler_falls_back(cache, monkeypatch, caplog):
    monkeypatch.setenv("CC", "false")  # runs, but fails (its --version prints nothing)
    functions = make_functions()
    result = compile_functions("test_lib", functions)
    assert all(result[f.name()] is f for f in functions)
    assert len(_said(caplog)) == 1
    assert not cache.exists() or list(cache.iterdir()) == []


def test_unwritable_cache_falls_back(tmp_path, monkeypatch, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("BASLIP_CACHE_DIR", str(blocker / "cache"))  # parent is a file
    monkeypatch.delenv("BASLIP_NO_COMPILE", raising=False)
    monkeypatch.delenv("CC", raising=False)
    functions = make_functions()
    result = compile_functions("test_lib", functions)
    assert all(result[f.name()] is f for f in functions)
    [line] = _said(caplog)
    assert "not writable" in line


@pytest.mark.parametrize("value", ["1", "yes"])
def test_no_compile_returns_the_originals_silently(cache, monkeypatch, caplog, value):
    monkeypatch.setenv("BASLIP_NO_COMPILE", value)
    functions = make_functions()
    result = compile_functions("test_lib", functions)
    assert all(result[f.name()] is f for f in functions)
    assert _said(caplog) == []
    assert not cache.exists()


def test_enabled_false_returns_the_originals(cache, caplog):
    functions = make_functions()
    result = compile_functions("test_lib", functions, enabled=False)
    assert all(result[f.name()] is f for f in functions)
    assert _said(caplog) == [] and not cache.exists()


def test_no_compile_zero_still_compiles(cache, monkeypatch):
    monkeypatch.setenv("BASLIP_NO_COMPILE", "0")
    result = compile_functions("test_lib", make_functions())
    assert all(g.is_a("External") for g in result.values())


def test_invalid_names_are_rejected(cache):
    with pytest.raises(ValueError):
        compile_functions("not-an-identifier", make_functions())
    f, _ = make_functions()
    with pytest.raises(ValueError):
        compile_functions("test_lib", [f, f])


def test_corrupt_library_is_rebuilt(cache, caplog):
    functions = make_functions()
    compile_functions("test_lib", functions)
    [library] = cache.glob("*.so")
    library.write_bytes(b"\x7fELF garbage, not a library")
    compiled = compile_functions("test_lib", functions)
    assert all(g.is_a("External") for g in compiled.values())
    assert_same_results(functions, compiled)
    assert libraries(cache) == [library.name]
    assert _said(caplog) == []


TRUNCATED_RUN = """
import numpy as np, sys
sys.path.insert(0, {tests!r})
from test_compile import make_functions, assert_same_results
from baslip.engine.codegen import compile_functions
functions = make_functions()
compiled = compile_functions("test_lib", functions)
assert all(g.is_a("External") for g in compiled.values())
assert_same_results(functions, compiled)
"""


def test_a_truncated_library_is_rebuilt_not_loaded(cache):
    """A library cut short (a full disk, a killed copy) may map cleanly and then kill the
    process with SIGBUS when called: its checksum no longer matches, so it is rebuilt."""
    code = TRUNCATED_RUN.format(tests=str(pathlib.Path(__file__).parent))
    env = {**os.environ, "BASLIP_CACHE_DIR": str(cache)}
    first = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    [library] = cache.glob("*.so")
    whole = library.read_bytes()
    assert (cache / f"{library.name}.sha256").read_text().strip() == hashlib.sha256(whole).hexdigest()
    for keep in (len(whole) // 2, 4096, 0):
        library.write_bytes(whole[:keep])
        again = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert again.returncode == 0, (keep, again.returncode, again.stderr[-500:])
        assert again.stderr == "" and library.read_bytes() == whole


def test_a_library_without_its_checksum_is_rebuilt(cache, caplog):
    functions = make_functions()
    compile_functions("test_lib", functions)
    [library] = cache.glob("*.so")
    (cache / f"{library.name}.sha256").unlink()
    compiled = compile_functions("test_lib", functions)
    assert_same_results(functions, compiled)
    assert (cache / f"{library.name}.sha256").exists() and _said(caplog) == []


def test_two_processes_starting_at_once_compile_once(cache, tmp_path, monkeypatch):
    """Two processes ask for the same library at the same moment: one compiles it under
    the lock, the other waits and loads it; both get compiled functions."""
    log = tmp_path / "compiles"
    wrapper = tmp_path / "cc"
    wrapper.write_text(
        textwrap.dedent(
            f"""\
            #!/bin/sh
            case " $* " in *" -shared "*) echo compile >> {log}; sleep 1;; esac
            exec gcc "$@"
            """
        )
    )
    wrapper.chmod(0o755)
    monkeypatch.setenv("CC", str(wrapper))
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {os.path.dirname(__file__)!r})
        from test_compile import make_functions
        from baslip.engine.codegen import compile_functions
        compiled = compile_functions("test_lib", make_functions())
        assert all(g.is_a("External") for g in compiled.values()), compiled
        print("ok")
        """
    )
    processes = [
        subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    outputs = [p.communicate(timeout=120) for p in processes]
    for process, (out, err) in zip(processes, outputs):
        assert process.returncode == 0, err
        assert out.strip() == "ok" and err == ""
    assert log.read_text().split() == ["compile"]  # compiled once
    assert len(libraries(cache)) == 1
    leftovers = [p.name for p in cache.iterdir() if not p.name.endswith((".so", ".so.sha256", ".lock"))]
    assert leftovers == []  # no temporary files


# -- kernels: the same functions called through ctypes ------------------------------------


def kernel_functions():
    """make_functions() plus a function of a matrix with a sparse output."""
    m = ca.SX.sym("m", 3, 2)
    sparse = ca.Function("g", [m], [ca.diag(ca.vertcat(m[0, 0] * m[1, 1], ca.sin(m[2, 1]))), m.T @ m])
    return [*make_functions(), sparse]


def test_native_kernels_give_the_virtual_machine_numbers(cache):
    from baslip.engine.codegen import compile_kernels

    functions = kernel_functions()
    sources = [pathlib.Path(__file__)]
    native = compile_kernels("kernels", [f.name() for f in functions], lambda: functions, sources)
    vm = compile_kernels("kernels", [f.name() for f in functions], lambda: functions, sources, enabled=False)
    assert type(native["f"]).__name__ == "NativeKernel" and type(vm["f"]).__name__ == "VirtualMachineKernel"
    rng = np.random.default_rng(0)
    for _ in range(5):
        x, m = rng.normal(size=3), rng.normal(size=(3, 2))
        for name, args in (("f", [x]), ("f_jac", [x]), ("g", [m])):
            for got, want in zip(native[name](*args), vm[name](*args)):
                assert got.shape == want.shape
                np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)


def test_kernels_load_from_the_cache_without_building(cache):
    from baslip.engine.codegen import compile_kernels

    functions = kernel_functions()
    names, sources = [f.name() for f in functions], [pathlib.Path(__file__)]
    compile_kernels("kernels", names, lambda: functions, sources)

    def must_not_build():
        raise AssertionError("a warm cache must not build the functions")

    kernels = compile_kernels("kernels", names, must_not_build, sources)
    assert kernels["f"]([0.1, 0.2, 0.3])[0].shape == (3, 1)


SLOW_COMPILER = """#!/bin/sh
# A compiler that hands its work to a child (as gcc hands it to cc1) and takes a minute.
case " $* " in *" -shared "*) sleep 60 & echo $! > {marker}; wait; exit 1;; esac
exec gcc "$@"
"""

COMPILE_ONCE = """
import sys
sys.path.insert(0, {tests!r})
from test_compile import make_functions
from baslip.engine.codegen import compile_functions
compiled = compile_functions("test_lib", make_functions())
assert all(g.is_a("External") for g in compiled.values()), compiled
"""


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to watch processes")
def test_a_killed_first_compile_leaves_no_process_and_the_next_build_clears_its_files(cache, tmp_path):
    """kill -9 during a compile: the compiler and its child end within half a second;
    the temporaries it leaves in the cache are removed by the next build of the library."""
    from processes import descendants, gone

    marker, wrapper = tmp_path / "cc1.pid", tmp_path / "cc"
    wrapper.write_text(SLOW_COMPILER.format(marker=marker))
    wrapper.chmod(0o755)
    code = COMPILE_ONCE.format(tests=str(pathlib.Path(__file__).parent))
    env = {**os.environ, "BASLIP_CACHE_DIR": str(cache), "CC": str(wrapper)}
    run = subprocess.Popen([sys.executable, "-c", code], env=env, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not (marker.exists() and marker.read_text().strip()) and time.monotonic() < deadline:
        time.sleep(0.01)
    grandchild = int(marker.read_text())
    children = descendants(run.pid)
    assert grandchild in children and len(children) >= 3  # the shell, the compiler, its child
    run.kill()
    run.wait()
    time.sleep(0.5)
    assert [pid for pid in children if not gone(pid)] == []
    left = sorted(p.name for p in cache.iterdir() if p.name.startswith("."))
    assert any(n.endswith(".tmp") for n in left) and any(n.endswith(".cc") for n in left)

    wrapper.write_text('#!/bin/sh\nexec gcc "$@"\n')  # the same compiler (so the same key), now quick
    again = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert again.returncode == 0 and again.stderr == "", again.stderr
    assert sorted(p.name for p in cache.iterdir() if p.name.startswith(".")) == []


def test_stale_temporaries_of_other_libraries_are_cleared_once_old(cache):
    """A killed build of a library that is never built again leaves its temporaries; any
    build removes those older than STALE_AFTER, and leaves younger ones (a live build)."""
    from baslip.engine.cachefiles import STALE_AFTER

    cache.mkdir()
    old, young = cache / ".other-0123.abc.tmp", cache / ".other-0123.def.cc"
    old.write_bytes(b"partial library")
    young.mkdir()
    (young / "other.c").write_text("int x;")
    past = time.time() - STALE_AFTER - 60
    os.utime(old, (past, past))
    compile_functions("test_lib", make_functions())
    assert not old.exists() and young.is_dir()


def test_a_notice_is_shown_once_per_reason_and_names_it(tmp_path, monkeypatch, caplog):
    """Three libraries that cannot be cached give one line, which blames the cache (not the
    compiler); what each ran on is recorded for provenance."""
    from baslip.engine.codegen import recording_code

    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("BASLIP_CACHE_DIR", str(blocker))
    monkeypatch.delenv("BASLIP_NO_COMPILE", raising=False)
    monkeypatch.delenv("CC", raising=False)
    with recording_code() as used:
        for name in ("lib_a", "lib_b", "lib_c"):
            compile_functions(name, make_functions())
    [line] = _said(caplog)
    assert "compiled-code cache" in line and "not a folder" in line and "no working C compiler" not in line
    assert sorted(used) == ["lib_a", "lib_b", "lib_c"]
    assert all(route.startswith("CasADi virtual machine (the compiled-code cache") for route in used.values())


def test_what_ran_is_recorded_per_library(cache, monkeypatch):
    from baslip.engine.codegen import recording_code

    with recording_code() as used:
        compile_functions("lib_c", make_functions())
        compile_functions("lib_vm", make_functions(), enabled=False)
    assert used["lib_c"].startswith("compiled C (") and "gcc" in used["lib_c"]
    assert used["lib_vm"] == "CasADi virtual machine (compiling switched off: by the caller)"


@pytest.mark.parametrize("home", ["", "/"])
def test_an_empty_home_gives_no_cache_at_the_root(monkeypatch, home):
    """HOME empty (Python then takes it to be /) or /: never /.cache/baslip. The user
    database's home is used if it is a real folder, else there is no cache."""
    monkeypatch.delenv("BASLIP_CACHE_DIR", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", home)
    found = cache_dir()
    assert found is None or (found.is_absolute() and found.parts[1] != ".cache")


def test_no_home_at_all_runs_in_the_virtual_machine_with_one_line(monkeypatch, caplog):
    import baslip.engine.codegen as codegen

    monkeypatch.delenv("BASLIP_CACHE_DIR", raising=False)
    monkeypatch.delenv("BASLIP_NO_COMPILE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/ignored")
    monkeypatch.setattr(codegen, "_home", lambda: None)
    functions = make_functions()
    result = compile_functions("lib_nohome", functions)
    assert all(result[f.name()] is f for f in functions)
    [line] = _said(caplog)
    assert "HOME is empty or unset; set BASLIP_CACHE_DIR" in line
