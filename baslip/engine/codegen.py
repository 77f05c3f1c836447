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
* Without a working compiler or a writable cache the original Functions are returned
  (one line on stderr says so): slower, same results. Setting ``BASLIP_NO_COMPILE=1``
  or passing ``enabled=False`` returns them silently.

The flags keep results IEEE-exact: no ``-ffast-math``, no ``-march=native``, and
``-ffp-contract=off`` so that no compiler fuses ``a*b + c`` into one FMA (GCC does by
default on targets that have FMA in their base instruction set, such as aarch64).
"""

from __future__ import annotations

import contextlib
import ctypes
import fcntl
import hashlib
import os
import pathlib
import re
import shlex
import subprocess
import sys
import tempfile
import types
from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

#: Flags after the compiler command: optimised, position-independent shared library.
CFLAGS = ("-O3", "-fPIC", "-shared", "-ffp-contract=off")
#: Libraries after the source file (the generated code calls sin, cos, ... of libm).
LDLIBS = ("-lm",)
#: Seconds after which a compiler run (or its ``--version`` probe) is abandoned.
COMPILER_TIMEOUT = 600.0
#: Library names: CasADi prefixes the generated C symbols with the name.
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


class _NoCompiler(Exception):
    """The C route failed; the message is the short reason shown to the user."""


def cache_dir() -> pathlib.Path:
    """$BASLIP_CACHE_DIR if set, else $XDG_CACHE_HOME/baslip, else ~/.cache/baslip."""
    if os.environ.get("BASLIP_CACHE_DIR"):
        return pathlib.Path(os.environ["BASLIP_CACHE_DIR"])
    if os.environ.get("XDG_CACHE_HOME"):
        return pathlib.Path(os.environ["XDG_CACHE_HOME"]) / "baslip"
    return pathlib.Path.home() / ".cache" / "baslip"


def compile_functions(
    name: str, functions: Sequence[ca.Function], *, enabled: bool | None = None
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
    if not _compiling(enabled):
        return originals
    c_text = _generate(name, functions)
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


def _compiling(enabled: bool | None) -> bool:
    """Whether to compile: ``enabled`` if given, else unless BASLIP_NO_COMPILE is set."""
    if enabled is not None:
        return enabled
    return os.environ.get("BASLIP_NO_COMPILE", "") in ("", "0")


def code_path() -> str:
    """What evaluates the model in this environment: compiled C, or CasADi's virtual
    machine and why (the same decision :func:`compile_kernels` makes)."""
    if not _compiling(None):
        return "CasADi virtual machine (BASLIP_NO_COMPILE is set)"
    try:
        return f"compiled C ({_compiler_version(_compiler())})"
    except _NoCompiler as reason:
        return f"CasADi virtual machine (no working C compiler: {reason})"


def _generate(name: str, functions: Sequence[ca.Function]) -> str:
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
        raise _NoCompiler(f"CC={os.environ['CC']!r}: {error}") from None


def _compiler_version(compiler: list[str]) -> str:
    """First line of ``compiler --version``; raises _NoCompiler if it does not run."""
    result = _run([*compiler, "--version"])
    lines = result.stdout.splitlines() or [""]
    return lines[0].strip()


def _run(command: list[str]) -> subprocess.CompletedProcess:
    """Run ``command`` with output captured; raises _NoCompiler if it cannot or fails."""
    try:
        result = subprocess.run(
            command,
            capture_output=True,
            text=True,
            errors="replace",
            timeout=COMPILER_TIMEOUT,
            check=False,
        )
    except FileNotFoundError:
        raise _NoCompiler(f"{command[0]} not found") from None
    except subprocess.TimeoutExpired:
        raise _NoCompiler(f"{command[0]} timed out after {COMPILER_TIMEOUT:g} s") from None
    except OSError as error:
        raise _NoCompiler(f"{command[0]}: {error.strerror or error}") from None
    if result.returncode != 0:
        first = (result.stderr.strip().splitlines() or [""])[0]
        raise _NoCompiler(f"{command[0]} exited with status {result.returncode}: {first}")
    return result


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


def _build(name: str, c_text: str, compiler: list[str], library: pathlib.Path) -> None:
    """Compile ``c_text`` into ``library``, atomically; raises _NoCompiler on failure.

    The source goes to a private temporary directory, the library to a unique
    temporary file in the cache directory that is renamed onto ``library``; neither
    temporary survives, whatever happens.
    """
    try:
        library.parent.mkdir(parents=True, exist_ok=True)
        handle, partial = tempfile.mkstemp(
            dir=library.parent, prefix=f".{library.stem}.", suffix=".tmp"
        )
        os.close(handle)
    except OSError as error:
        raise _NoCompiler(f"cache {library.parent} not writable: {error.strerror}") from None
    try:
        with tempfile.TemporaryDirectory(prefix="baslip-cc-") as scratch:
            source = pathlib.Path(scratch) / f"{name}.c"
            source.write_text(c_text, encoding="utf-8")
            _run([*compiler, *CFLAGS, str(source), "-o", partial, *LDLIBS])
        digest = _sha256(pathlib.Path(partial))
        os.replace(partial, library)
        _write_checksum(library, digest)
    except OSError as error:
        raise _NoCompiler(f"cannot write the library: {error.strerror or error}") from None
    finally:
        _discard(partial)


# -- kernels: compiled functions called through ctypes --------------------------------------
#
# Calling a loaded library through ``casadi.external`` converts every input and output
# between numpy and DM, about 35 us a call: more than a whole compiled stride phase. A
# kernel calls the generated C entry point directly, with buffers allocated once.


class Kernel:
    """A callable returning each output as a 2-D numpy array (column-major like CasADi)."""

    name: str

    def __call__(self, *args) -> tuple[np.ndarray, ...]:  # pragma: no cover - interface
        raise NotImplementedError


class VirtualMachineKernel(Kernel):
    """A CasADi Function in its virtual machine, behind the kernel interface."""

    def __init__(self, function: ca.Function):
        self.function = function
        self.name = function.name()

    def __call__(self, *args) -> tuple[np.ndarray, ...]:
        return tuple(out.full() for out in self.function.call([ca.DM(np.asarray(a, dtype=float)) for a in args]))


class NativeKernel(Kernel):
    """The entry point ``name`` of a library generated by CasADi, called through ctypes.

    Inputs are copied into buffers held by the kernel, so a kernel is not reentrant: use
    one per thread.
    """

    def __init__(self, library: ctypes.CDLL, name: str):
        self.name = name
        self._entry = _symbol(library, name, ctypes.c_int,
                              [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int])
        n_in = _symbol(library, f"{name}_n_in", _CASADI_INT, [])()
        n_out = _symbol(library, f"{name}_n_out", _CASADI_INT, [])()
        sparsity_in = _symbol(library, f"{name}_sparsity_in", ctypes.POINTER(_CASADI_INT), [_CASADI_INT])
        sparsity_out = _symbol(library, f"{name}_sparsity_out", ctypes.POINTER(_CASADI_INT), [_CASADI_INT])
        self._inputs = [_Slot(sparsity_in(i)) for i in range(n_in)]
        self._outputs = [_Slot(sparsity_out(i)) for i in range(n_out)]
        sizes = [_CASADI_INT() for _ in range(4)]
        _symbol(library, f"{name}_work", ctypes.c_int, [ctypes.POINTER(_CASADI_INT)] * 4)(*sizes)
        sz_arg, sz_res, sz_iw, sz_w = (max(int(s.value), 1) for s in sizes)
        self._arg = (ctypes.c_void_p * max(sz_arg, n_in))(*[s.data.ctypes.data for s in self._inputs])
        self._res = (ctypes.c_void_p * max(sz_res, n_out))(*[s.data.ctypes.data for s in self._outputs])
        self._iw = np.zeros(sz_iw, dtype=np.int64)
        self._w = np.zeros(sz_w)
        self._iw_pointer, self._w_pointer = self._iw.ctypes.data, self._w.ctypes.data
        self._mem = _symbol(library, f"{name}_checkout", ctypes.c_int, [])()
        self._library = library  # keeps the library loaded while the kernel lives

    def __call__(self, *args) -> tuple[np.ndarray, ...]:
        for slot, value in zip(self._inputs, args):
            slot.fill(value)
        status = self._entry(self._arg, self._res, self._iw_pointer, self._w_pointer, self._mem)
        if status:
            raise RuntimeError(f"{self.name} returned status {status}")
        return tuple(slot.dense() for slot in self._outputs)


_CASADI_INT = ctypes.c_longlong


class _Slot:
    """The buffer of one input or output, with its CasADi sparsity pattern."""

    def __init__(self, pattern):
        nrow, ncol = int(pattern[0]), int(pattern[1])
        if pattern[2] == 1:  # CasADi's compact form of a dense pattern: (nrow, ncol, 1)
            colind = np.arange(ncol + 1, dtype=np.int64) * nrow
            rows = np.tile(np.arange(nrow, dtype=np.int64), ncol)
        else:
            colind = np.array([pattern[2 + j] for j in range(ncol + 1)], dtype=np.int64)
            rows = np.array([pattern[3 + ncol + k] for k in range(int(colind[-1]))], dtype=np.int64)
        nnz = int(colind[-1])
        self.shape = (nrow, ncol)
        self.data = np.zeros(max(nnz, 1))
        self.is_dense = nnz == nrow * ncol
        # Flat column-major positions of the nonzeros, for sparse outputs.
        self._positions = rows + nrow * np.repeat(np.arange(ncol), np.diff(colind))
        self._nnz = nnz

    def fill(self, value) -> None:
        if self.is_dense:
            try:
                self.data[: self._nnz] = value  # vectors and scalars, without a copy
                return
            except ValueError:  # a matrix (or an n x 1 array): flatten column-major
                pass
        flat = np.asarray(value, dtype=float).ravel(order="F")
        self.data[: self._nnz] = flat if self.is_dense else flat[self._positions]

    def dense(self) -> np.ndarray:
        if self.is_dense:
            return self.data[: self._nnz].reshape(self.shape, order="F").copy()
        out = np.zeros(self.shape[0] * self.shape[1])
        out[self._positions] = self.data[: self._nnz]
        return out.reshape(self.shape, order="F")


def _symbol(library: ctypes.CDLL, name: str, restype, argtypes):
    entry = getattr(library, name)
    entry.restype, entry.argtypes = restype, argtypes
    return entry


def compile_kernels(
    name: str,
    names: Sequence[str],
    build: Callable[[], Sequence[ca.Function]],
    sources: Sequence[pathlib.Path],
    *,
    enabled: bool | None = None,
    settings: str = "",
) -> dict[str, Kernel]:
    """Kernels for the functions ``names`` that ``build()`` makes, compiled and cached.

    The cache key hashes the ``sources`` (the Python modules the functions are derived
    from), the names, ``settings`` (anything else the functions depend on, such as
    integrator tolerances), the CasADi version, the compiler and its flags, so a warm
    process loads the library without building or generating anything. ``enabled`` and
    the fallback behave as in :func:`compile_functions`; the fallback's kernels run in
    the VM.
    """
    fingerprint = [*_read(sources), settings.encode()]
    return _cached(name, names, build, fingerprint, enabled, _native_kernels, _vm_kernels)


def compile_library(
    name: str,
    names: Sequence[str],
    build: Callable[[], Sequence[ca.Function]],
    sources: Sequence[pathlib.Path],
    *,
    enabled: bool | None = None,
) -> dict[str, ca.Function]:
    """As :func:`compile_kernels`, but as CasADi Functions (``casadi.external``), for
    use inside other CasADi objects such as an NLP solver, which call them from C++."""
    return _cached(name, names, build, _read(sources), enabled, _load, lambda functions: {f.name(): f for f in functions})


def _cached(name, names, build, fingerprint: Sequence[bytes], enabled, load, fallback, generated: str | None = None):
    """The library of ``names``, keyed by ``fingerprint`` (the generated C, or the sources
    it is derived from) with the CasADi version and the compiler: loaded, or else built
    under a lock, compiled and loaded; ``fallback(build())`` without a compiler or with
    compiling switched off. ``generated`` is the C text when the caller has it already."""
    if not _NAME.fullmatch(name):
        raise ValueError(f"library name {name!r} is not a C identifier")
    if not _compiling(enabled):
        return fallback(build())
    try:
        compiler = _compiler()
        key = _key(fingerprint, names, compiler, _compiler_version(compiler))
        library = cache_dir() / f"{name}-{key[:20]}.so"
        loaded = load(library, names) if _intact(library) else None
        if loaded is not None:
            return loaded
        with _build_lock(library):
            # Another process may have built it while this one waited for the lock.
            loaded = load(library, names) if _intact(library) else None
            if loaded is not None:
                return loaded
            _discard(library)  # corrupt, truncated or stale: rebuild once
            _discard(_checksum_path(library))
            _build(name, generated if generated is not None else _generate(name, build()), compiler, library)
        loaded = load(library, names)
        if loaded is None:
            raise _NoCompiler(f"the freshly compiled {library.name} does not load")
        return loaded
    except _NoCompiler as reason:
        print(
            f"baslip: no working C compiler ({reason}); "
            "using CasADi's virtual machine (slower, same results)",
            file=sys.stderr,
        )
        return fallback(build())


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


def module_files(*modules: types.ModuleType) -> list[pathlib.Path]:
    """The source files of ``modules``: the key of a library derived from them.

    Taken from the module objects themselves, so that moving or renaming a module
    cannot leave a stale file name in a library's key.
    """
    return [pathlib.Path(module.__file__) for module in modules]  # type: ignore[arg-type]


def _read(sources: Sequence[pathlib.Path]) -> list[bytes]:
    return [pathlib.Path(source).read_bytes() for source in sources]


def _key(fingerprint: Sequence[bytes], names: Sequence[str], compiler: list[str], version: str) -> str:
    """sha256 of everything that decides a library's contents."""
    digest = hashlib.sha256()
    parts = [*fingerprint, " ".join(names).encode(), ca.__version__.encode(),  # type: ignore[attr-defined]
             shlex.join([*compiler, *CFLAGS, *LDLIBS]).encode(), version.encode()]
    for part in parts:
        digest.update(part)
        digest.update(b"\0")
    return digest.hexdigest()


@contextlib.contextmanager
def _build_lock(library: pathlib.Path):
    """Hold an exclusive lock beside ``library`` while it is built, so that processes
    starting together compile it once; without locking (or a writable cache) each process
    builds its own copy, which the atomic rename still makes safe."""
    try:
        library.parent.mkdir(parents=True, exist_ok=True)
        handle = open(library.with_suffix(".lock"), "w")
    except OSError:
        yield
        return
    with handle:
        with contextlib.suppress(OSError):
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield
