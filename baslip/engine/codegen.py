"""Compile CasADi Functions to C and cache the shared libraries on disk.

CasADi evaluates a Function in its virtual machine (VM) unless the Function is
code-generated, compiled and loaded back with :func:`casadi.external`; the compiled
version runs several times faster and gives the same numbers. :func:`compile_functions`
does this for a list of Functions at once:

* One C file holds all Functions (dependencies they share are emitted once).
* The library is cached as ``cache_dir()/<name>-<key>.so``, where ``key`` hashes the C
  text, the CasADi version, the compiler command and flags and the compiler's version,
  so a change to any of them builds a new library and a cached one is never stale.
* The library is compiled to a unique temporary file next to its final name and
  renamed into place, an atomic step: processes compiling the same key at once are
  both safe, and no process ever loads a half-written library.
* Its SHA-256 is written beside it (``<library>.sha256``, also atomically), and a
  library is loaded only if it matches: a truncated or damaged one (which the dynamic
  loader may map and then die on, with SIGBUS) is rebuilt, never loaded.
* The compiler runs in a process group of its own that dies with this process (see
  :mod:`baslip.children`), and its temporaries live in the cache as ``.<library>.*``: the
  next build removes what a killed one left.
* Without a working compiler or a writable cache the original Functions are returned,
  with one line on stderr naming the reason (once per reason, in a study too): slower,
  same results. Setting ``BASLIP_NO_COMPILE=1`` or passing ``enabled=False`` returns
  them silently.
* A library that a run calls only a few times (``enabled=FEW_CALLS``) is compiled at
  gcc's quickest level unless the cache holds it at its own (same numbers).
* What each library loaded inside :func:`recording_code` runs on is recorded, for
  provenance: compiled C, or the virtual machine and why.
* The compiler's version (part of every key) is asked once per process and compiler.
* Building, compiling and loading count as set-up (:mod:`baslip.engine.setuptime`).

The flags keep results IEEE-exact: no ``-ffast-math``, no ``-march=native``, and
``-ffp-contract=off`` so that no compiler fuses ``a*b + c`` into one FMA (GCC does by
default on targets that have FMA in their base instruction set, such as aarch64).
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import pathlib
import pwd
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import types
from collections.abc import Callable, Iterator, Sequence

import casadi as ca

from baslip.diagnostics import logger
from baslip.engine.announce import announced
from baslip.engine.cachefiles import COMPILER_TIMEOUT, build_lock, clear_stale
from baslip.engine.native import Kernel, NativeKernel, VirtualMachineKernel
from baslip.engine.setuptime import setting_up

_log = logger(__name__)

#: Flags after the compiler command: optimised, position-independent shared library. The
#: first is the optimisation level, which a library may choose (:func:`compile_kernels`).
CFLAGS = ("-O3", "-fPIC", "-shared", "-ffp-contract=off")
#: The optimisation level of a library that does not choose one.
OPTIMISATION = CFLAGS[0]
#: Libraries after the source file (the generated code calls sin, cos, ... of libm).
LDLIBS = ("-lm",)
#: Library names: CasADi prefixes the generated C symbols with the name.
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


class _NoCompiler(Exception):
    """The C route failed; the message is the short reason shown to the user."""


def cache_dir() -> pathlib.Path | None:
    """Where compiled libraries are kept: ``$BASLIP_CACHE_DIR`` if set, else
    ``$XDG_CACHE_HOME/baslip`` (if absolute, as the XDG rules ask), else
    ``~/.cache/baslip``, with the home folder taken from ``$HOME`` or, when that is empty
    or not absolute, from the user database. None when there is no home folder either
    (a home of ``/`` counts as none): nothing is then compiled, and one line says so."""
    if os.environ.get("BASLIP_CACHE_DIR"):
        return pathlib.Path(os.environ["BASLIP_CACHE_DIR"])
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    if os.path.isabs(xdg):
        return pathlib.Path(xdg) / "baslip"
    home = _home()
    return None if home is None else home / ".cache" / "baslip"


def _home() -> pathlib.Path | None:
    """The user's home folder: $HOME, else the user database's; None if neither is an
    absolute path other than the root."""
    candidates = [os.environ.get("HOME", "")]
    with contextlib.suppress(KeyError):
        candidates.append(pwd.getpwuid(os.getuid()).pw_dir)
    for candidate in candidates:
        if os.path.isabs(candidate) and pathlib.Path(candidate) != pathlib.Path("/"):
            return pathlib.Path(candidate)
    return None


# -- what ran: a record of this process ------------------------------------------------------


class _ProcessRecord:
    """What the libraries loaded by this process run on, and which fallback notices it
    has shown. The one piece of process state in baslip, on purpose: which code ran, and
    whether the user was told, are facts about the process rather than about one object."""

    def __init__(self) -> None:
        self.recordings: list[dict[str, str]] = []
        self.noticed: set[str] = set()
        self.notices_here = True
        self.compiler_versions: dict[tuple[str, ...], str] = {}  # asked once per process


_PROCESS = _ProcessRecord()

#: The start of the description of a library that runs as compiled C.
COMPILED_C = "compiled C"
#: The start of the description of a library that runs in CasADi's virtual machine.
VIRTUAL_MACHINE = "CasADi virtual machine"


@contextlib.contextmanager
def recording_code() -> Iterator[dict[str, str]]:
    """Collect what every library loaded inside the block runs on.

    Yields
    ------
    dict
        Filled as libraries load: library name -> ``"compiled C (<compiler version>)"``
        or ``"CasADi virtual machine (<why>)"``; a library that ran both ways (in two
        processes, say) lists both, separated by ``"; "``. This is what provenance's
        ``code`` records.
    """
    used: dict[str, str] = {}
    _PROCESS.recordings.append(used)
    try:
        yield used
    finally:
        _PROCESS.recordings.remove(used)


def note_code(routes: dict[str, str]) -> None:
    """Add what another process (a study's worker) reported running to the open
    recordings, and show here, once each, the fallback notices it left to this process."""
    for name, route in routes.items():
        for part in route.split("; "):
            _note(name, part)


def leave_notices_to_parent() -> None:
    """In a worker: show no fallback notice here; the parent shows them, once each, from
    what the worker reports (:func:`note_code`)."""
    _PROCESS.notices_here = False


def _note(name: str, route: str) -> None:
    """Record that library ``name`` runs on ``route``, and show a fallback's reason once."""
    for used in _PROCESS.recordings:
        known = used[name].split("; ") if name in used else []
        used[name] = "; ".join(sorted({*known, route}))
    reason = route[len(VIRTUAL_MACHINE) + 2:-1] if route.startswith(VIRTUAL_MACHINE + " (") else ""
    if reason and not reason.startswith(_SWITCHED_OFF) and _PROCESS.notices_here and reason not in _PROCESS.noticed:
        _PROCESS.noticed.add(reason)
        _log.warning(f"baslip: {reason}; using CasADi's virtual machine instead (slower, same results)")


#: How a fallback that was asked for is described (no notice is shown for it).
_SWITCHED_OFF = "compiling switched off"
#: ``enabled`` of a library that a run calls only a few times (a one-gait solve: a few
#: hundred NLP evaluations, a dozen strides, a few Jacobians): compiled like any other,
#: but at :data:`QUICK_OPTIMISATION` unless the cache holds it at its own level already.
#: Studies, continuation and anything else that calls a library many times pass None.
FEW_CALLS = "few calls"
#: gcc's level for :data:`FEW_CALLS`. On the 2-core machine (busy): one step count's Jacobian
#: compiles in 2.0 s at -O0 against 21.5 s at -O1 and runs in 18 ms against 6 ms (90 ms in the
#: VM); the quick start's gait, residual and multipliers are the same to the bit.
QUICK_OPTIMISATION = "-O0"


def note_switched_off(name: str, enabled: bool | str | None) -> None:
    """Record that library ``name`` runs in the virtual machine because compiling is off."""
    why = "BASLIP_NO_COMPILE is set" if enabled in (None, FEW_CALLS) else "by the caller"
    _note(name, f"{VIRTUAL_MACHINE} ({_SWITCHED_OFF}: {why})")


def compile_functions(
    name: str, functions: Sequence[ca.Function], *, enabled: bool | str | None = None
) -> dict[str, ca.Function]:
    """Return {f.name(): callable Function} for each input function, compiled to C and loaded from the disk cache when possible, else the originals (CasADi virtual machine).

    ``name`` names the library (a C identifier: letters, digits, underscores). ``enabled``
    True or False forces compiling on or off; None (the default) compiles unless the
    environment variable ``BASLIP_NO_COMPILE`` is set to something other than "" or "0".
    The returned Functions take the same inputs as the originals; derivatives of them
    are not available, so pass derivative Functions (e.g. a Jacobian) in ``functions``.

    Raises ValueError for an invalid ``name`` or two Functions with one name, and
    CasADi's RuntimeError for a Function that cannot be code-generated: those are
    programming errors. A missing or failing compiler or an unwritable cache is not an
    error: the originals are returned with one line on stderr.
    """
    originals = _by_name(name, functions)
    if not compiling(enabled):
        note_switched_off(name, enabled)
        return originals
    c_text = generate_c(name, functions)
    return _cached(name, list(originals), lambda: functions, [c_text.encode()], True, _load, lambda _: originals,
                   generated=c_text)


def _by_name(name: str, functions: Sequence[ca.Function]) -> dict[str, ca.Function]:
    """The functions keyed by name, after checking the library name and unique names."""
    if not _NAME.fullmatch(name):
        raise ValueError(f"library name {name!r} is not a C identifier")
    originals = {f.name(): f for f in functions}
    if len(originals) != len(functions):
        raise ValueError(f"function names are not unique: {[f.name() for f in functions]}")
    return originals


def compiling(enabled: bool | str | None) -> bool:
    """Whether to compile: ``enabled`` if True or False, else (None or :data:`FEW_CALLS`)
    unless BASLIP_NO_COMPILE is set."""
    if isinstance(enabled, bool):
        return enabled
    return os.environ.get("BASLIP_NO_COMPILE", "") in ("", "0")


def generate_c(name: str, functions: Sequence[ca.Function]) -> str:
    """The C source of one file holding all ``functions``."""
    generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    for function in functions:
        generator.add(function)
    return generator.dump()


def _compiler() -> list[str]:
    """The compiler command: ``$CC`` (split like a shell would) if set, else gcc."""
    try:
        return shlex.split(os.environ.get("CC", "")) or ["gcc"]
    except ValueError as error:
        raise _NoCompiler(f"no working C compiler (CC={os.environ['CC']!r}: {error})") from None


def _compiler_version(compiler: list[str]) -> str:
    """First line of ``compiler --version``, asked once per process (and compiler), run
    directly rather than through :func:`_run`'s shell; raises _NoCompiler if it does not run."""
    key = tuple(compiler)
    if key not in _PROCESS.compiler_versions:
        try:
            result = subprocess.run([*compiler, "--version"], capture_output=True, text=True, errors="replace",
                                    timeout=COMPILER_TIMEOUT, check=False)
        except (OSError, subprocess.TimeoutExpired) as error:
            why = f"{compiler[0]} not found" if isinstance(error, FileNotFoundError) else f"{compiler[0]}: {error}"
            raise _NoCompiler(f"no working C compiler ({why})") from None
        if result.returncode != 0:
            first = (result.stderr.strip().splitlines() or [""])[0]
            raise _NoCompiler(f"no working C compiler ({compiler[0]} exited with status {result.returncode}: {first})")
        _PROCESS.compiler_versions[key] = (result.stdout.splitlines() or [""])[0].strip()
    return _PROCESS.compiler_versions[key]


def _run(command: list[str]) -> subprocess.CompletedProcess:
    """Run ``command`` with output captured; raises _NoCompiler if it cannot or fails.

    On Linux the command runs in a process group of its own, under a shell that kills
    the whole group when this process ends (see :mod:`baslip.children`): a killed run
    leaves no gcc or cc1 behind. A timeout or an interrupt kills the group too.
    """
    from baslip.children import compiler_preexec, in_own_group  # here: a warm run starts no process

    linux = sys.platform.startswith("linux")
    argv = in_own_group(command) if linux else command
    preexec = compiler_preexec(os.getpid()) if linux else None
    try:
        process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   errors="replace", start_new_session=linux, preexec_fn=preexec)
    except OSError as error:
        raise _NoCompiler(f"{command[0]}: {error.strerror or error}") from None
    try:
        stdout, stderr = process.communicate(timeout=COMPILER_TIMEOUT)
    except subprocess.TimeoutExpired:
        _kill_group(process)
        raise _NoCompiler(f"{command[0]} timed out after {COMPILER_TIMEOUT:g} s") from None
    except BaseException:
        _kill_group(process)
        raise
    if process.returncode == 127 and linux and "not found" in stderr:
        raise _NoCompiler(f"{command[0]} not found")
    if process.returncode == 126 and linux:
        raise _NoCompiler(f"{command[0]}: cannot be run")
    if process.returncode != 0:
        first = (stderr.strip().splitlines() or [""])[0]
        raise _NoCompiler(f"{command[0]} exited with status {process.returncode}: {first}")
    return subprocess.CompletedProcess(argv, process.returncode, stdout, stderr)


def _kill_group(process: subprocess.Popen) -> None:
    """Kill ``process`` and, if it leads a process group, everything in the group."""
    with contextlib.suppress(OSError):
        if sys.platform.startswith("linux"):
            os.killpg(process.pid, signal.SIGKILL)
        else:
            process.kill()
    process.communicate()


def _load(library: pathlib.Path, names: list[str]) -> dict[str, ca.Function] | None:
    """Every function of ``names`` loaded from ``library``, or None if any fails to load."""
    try:
        return {fname: ca.external(fname, str(library)) for fname in names}
    except RuntimeError:
        return None


def _discard(path: pathlib.Path | str) -> None:
    """Delete ``path`` if it exists and can be deleted; never raises."""
    with contextlib.suppress(OSError):
        os.unlink(path)


def _build(name: str, c_text: str, compiler: list[str], library: pathlib.Path, optimisation: str) -> None:
    """Compile ``c_text`` into ``library``, atomically; raises _NoCompiler on failure.

    The source goes to a private temporary directory and the library to a unique
    temporary file, both in the cache directory and named ``.<library stem>.*``; the
    library is renamed onto ``library``. Neither temporary survives an error; those of
    a killed process are removed by the next build (:func:`~baslip.engine.cachefiles.clear_stale`).
    """
    try:
        library.parent.mkdir(parents=True, exist_ok=True)
        handle, partial = tempfile.mkstemp(
            dir=library.parent, prefix=f".{library.stem}.", suffix=".tmp"
        )
        os.close(handle)
    except OSError as error:
        why = "it is not a folder" if library.parent.exists() and not library.parent.is_dir() else error.strerror
        raise _NoCompiler(f"the compiled-code cache {library.parent} is not writable ({why})") from None
    try:
        with tempfile.TemporaryDirectory(dir=library.parent, prefix=f".{library.stem}.", suffix=".cc") as scratch:
            source = pathlib.Path(scratch) / f"{name}.c"
            source.write_text(c_text, encoding="utf-8")
            try:
                with announced(_log, name, c_text, library.parent, optimisation):  # once the cache has taken the source
                    _run([*compiler, *_flags(optimisation), str(source), "-o", partial, *LDLIBS])
            except _NoCompiler as reason:
                raise _NoCompiler(f"compiling {name} failed ({reason})") from None
        digest = _sha256(pathlib.Path(partial))
        os.replace(partial, library)
        _write_checksum(library, digest)
    except OSError as error:
        raise _NoCompiler(f"the compiled-code cache {library.parent} is not writable "
                          f"({error.strerror or error})") from None
    finally:
        _discard(partial)


def compile_kernels(
    name: str,
    names: Sequence[str],
    build: Callable[[], Sequence[ca.Function]],
    sources: Sequence[pathlib.Path],
    *,
    enabled: bool | str | None = None,
    settings: str = "",
    optimisation: str = OPTIMISATION,
    generated: str | None = None,
) -> dict[str, Kernel]:
    """Kernels for the functions ``names`` that ``build()`` makes, compiled and cached.

    The cache key hashes the ``sources`` (the Python modules the functions are derived
    from), the names, ``settings`` (anything else the functions depend on, such as
    integrator tolerances), the CasADi version, the compiler and its flags, so a warm
    process loads the library without building or generating anything. ``enabled`` and
    the fallback behave as in :func:`compile_functions`; the fallback's kernels run in
    the VM. ``optimisation`` is gcc's level for this library (``-O3``, ``-O1``, ...);
    ``generated`` the C text of ``build()``'s functions, when the caller made it already.
    """
    fingerprint = [*_read(sources), settings.encode()]
    return _cached(name, names, build, fingerprint, enabled, _native_kernels, _vm_kernels, generated, optimisation)


def cached_kernels(name: str, names: Sequence[str], sources: Sequence[pathlib.Path], *, settings: str = "",
                   optimisation: str = OPTIMISATION) -> dict[str, Kernel] | None:
    """The kernels :func:`compile_kernels` would return, if the cache already holds an
    intact library of them (loaded, without building anything), else None."""
    with setting_up():
        return _load_cached(name, names, [*_read(sources), settings.encode()], _native_kernels, optimisation)


def cached_library(name: str, names: Sequence[str], sources: Sequence[pathlib.Path], *,
                   optimisation: str = OPTIMISATION) -> dict[str, ca.Function] | None:
    """The Functions :func:`compile_library` would return, if the cache already holds an
    intact library of them (loaded, without building anything), else None."""
    with setting_up():
        return _load_cached(name, names, _read(sources), _load, optimisation)


def library_file(name: str, names: Sequence[str], sources: Sequence[pathlib.Path], *,
                 optimisation: str = OPTIMISATION) -> pathlib.Path | None:
    """Where :func:`compile_library`'s library of this key lives in the cache (whether or
    not it is there yet); None without a compiler or a cache folder."""
    with contextlib.suppress(_NoCompiler):
        return _library_path(name, names, _read(sources), optimisation)[0]
    return None


def _load_cached(name, names, fingerprint: Sequence[bytes], load, optimisation: str):
    """The library of this key loaded from the cache if it holds an intact copy, else None."""
    with contextlib.suppress(_NoCompiler):
        library, _, version = _library_path(name, names, fingerprint, optimisation)
        loaded = load(library, names) if _intact(library) else None
        if loaded is not None:
            _note(name, f"{COMPILED_C} ({version})")
        return loaded
    return None


def compile_library(
    name: str,
    names: Sequence[str],
    build: Callable[[], Sequence[ca.Function]],
    sources: Sequence[pathlib.Path],
    *,
    enabled: bool | str | None = None,
    optimisation: str = OPTIMISATION,
) -> dict[str, ca.Function]:
    """As :func:`compile_kernels`, but as CasADi Functions (``casadi.external``), for
    use inside other CasADi objects such as an NLP solver, which call them from C++."""
    return _cached(name, names, build, _read(sources), enabled, _load, lambda functions: {f.name(): f for f in functions},
                   optimisation=optimisation)


def _cached(name, names, build, fingerprint: Sequence[bytes], enabled, load, fallback, generated: str | None = None,
            optimisation: str = OPTIMISATION):
    """The library of ``names``, keyed by ``fingerprint`` (the generated C, or the sources
    it is derived from) with the CasADi version and the compiler: loaded, or else built
    under a lock, compiled and loaded; ``fallback(build())`` without a compiler or with
    compiling switched off. ``generated`` is the C text when the caller has it already."""
    if not _NAME.fullmatch(name):
        raise ValueError(f"library name {name!r} is not a C identifier")
    with setting_up():
        if not compiling(enabled):
            note_switched_off(name, enabled)
            return fallback(build())
        if enabled == FEW_CALLS:
            tuned = _load_cached(name, names, fingerprint, load, optimisation)
            if tuned is not None:
                return tuned
            optimisation = QUICK_OPTIMISATION
        try:
            loaded, version = _load_or_build(name, names, build, fingerprint, load, generated, optimisation)
        except _NoCompiler as reason:
            _note(name, f"{VIRTUAL_MACHINE} ({reason})")
            return fallback(build())
        _note(name, f"{COMPILED_C} ({version})")
        return loaded


def _library_path(name, names, fingerprint, optimisation) -> tuple[pathlib.Path, list[str], str]:
    """(where the library of this key lives in the cache, the compiler, its version);
    raises _NoCompiler without a cache folder."""
    compiler = _compiler()
    version = _compiler_version(compiler)
    folder = cache_dir()
    if folder is None:
        raise _NoCompiler("there is no folder for compiled code (HOME is empty or unset; set BASLIP_CACHE_DIR)")
    return folder / f"{name}-{_key(fingerprint, names, compiler, version, optimisation)[:20]}.so", compiler, version


def _load_or_build(name, names, build, fingerprint, load, generated, optimisation):
    """(the loaded library, the compiler's version): from the cache if it holds an intact
    copy, else built under a lock first; raises _NoCompiler if neither works."""
    library, compiler, version = _library_path(name, names, fingerprint, optimisation)
    loaded = load(library, names) if _intact(library) else None
    if loaded is None:
        loaded = _build_and_load(name, names, build, load, generated, compiler, library, optimisation)
    return loaded, version


def _build_and_load(name, names, build, load, generated, compiler, library: pathlib.Path, optimisation: str):
    """Build ``library`` under its lock (unless another process did while this one
    waited) and load it; raises _NoCompiler if it cannot be built or does not load."""
    with build_lock(library) as locked:
        loaded = load(library, names) if _intact(library) else None
        if loaded is not None:
            return loaded
        clear_stale(library, locked)
        _discard(library)  # corrupt, truncated or stale: rebuild once
        _discard(_checksum_path(library))
        _build(name, generated if generated is not None else generate_c(name, build()), compiler, library, optimisation)
    loaded = load(library, names)
    if loaded is None:
        raise _NoCompiler(f"the freshly compiled {library.name} does not load")
    return loaded


def _checksum_path(library: pathlib.Path) -> pathlib.Path:
    return library.with_name(library.name + ".sha256")


def _sha256(path: pathlib.Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_checksum(library: pathlib.Path, digest: str) -> None:
    """``digest`` beside ``library``, written to a temporary file and renamed into place."""
    handle, partial = tempfile.mkstemp(dir=library.parent, prefix=f".{library.stem}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w") as out:
            out.write(digest + "\n")
        os.replace(partial, _checksum_path(library))
    finally:
        _discard(partial)


def _intact(library: pathlib.Path) -> bool:
    """Whether ``library`` is a regular file whose bytes match the checksum written at build."""
    try:
        if library.is_symlink() or not library.is_file():
            return False
        return _checksum_path(library).read_text().strip() == _sha256(library)
    except (OSError, UnicodeDecodeError):
        return False


def _vm_kernels(functions: Sequence[ca.Function]) -> dict[str, Kernel]:
    return {f.name(): VirtualMachineKernel(f) for f in functions}


def _native_kernels(library: pathlib.Path, names: Sequence[str]) -> dict[str, Kernel] | None:
    """Kernels of ``names`` from ``library``, or None if it does not load or lacks one."""
    try:
        loaded = ctypes.CDLL(str(library))
        return {n: NativeKernel(loaded, n) for n in names}
    except (OSError, AttributeError):
        return None


def library_name(base: str, law) -> str:
    """The name of a compiled library of hip law ``law`` (a
    :class:`~baslip.model.hiplaw.HipLaw`): the PD library keeps its bare name."""
    return base if law.name == "pd" else f"{base}_{law.name}"


def module_files(*modules: types.ModuleType) -> list[pathlib.Path]:
    """The source files of ``modules``: the key of a library derived from them.

    Taken from the module objects themselves, so that moving or renaming a module
    cannot leave a stale file name in a library's key.
    """
    return [pathlib.Path(module.__file__) for module in modules]  # type: ignore[arg-type]


def _read(sources: Sequence[pathlib.Path]) -> list[bytes]:
    return [pathlib.Path(source).read_bytes() for source in sources]


def _flags(optimisation: str) -> tuple[str, ...]:
    """The compiler's flags at an optimisation level (:data:`CFLAGS` at the default)."""
    return (optimisation, *CFLAGS[1:])


def _key(fingerprint: Sequence[bytes], names: Sequence[str], compiler: list[str], version: str,
         optimisation: str = OPTIMISATION) -> str:
    """sha256 of everything that decides a library's contents."""
    digest = hashlib.sha256()
    parts = [*fingerprint, " ".join(names).encode(), ca.__version__.encode(),  # type: ignore[attr-defined]
             shlex.join([*compiler, *_flags(optimisation), *LDLIBS]).encode(), version.encode()]
    for part in parts:
        digest.update(part)
        digest.update(b"\0")
    return digest.hexdigest()
