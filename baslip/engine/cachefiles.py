"""The compiled-code cache's own files: the lock a build holds, and the temporaries that
killed builds leave behind (see :mod:`baslip.engine.codegen`)."""

from __future__ import annotations

import contextlib
import fcntl
import pathlib
import shutil
import time

#: Seconds after which a compiler run (or its ``--version`` probe) is abandoned.
COMPILER_TIMEOUT = 600.0


@contextlib.contextmanager
def build_lock(library: pathlib.Path):
    """Hold an exclusive lock beside ``library`` while it is built, so that processes
    starting together compile it once; without locking (or a writable cache) each process
    builds its own copy, which the atomic rename still makes safe."""
    try:
        library.parent.mkdir(parents=True, exist_ok=True)
        handle = open(library.with_suffix(".lock"), "w")
    except OSError:
        yield False
        return
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)
        except OSError:
            yield False
        else:
            yield True


#: Seconds after which a temporary of any build in the cache is certainly abandoned: no
#: live build runs longer than the compiler's timeout.
STALE_AFTER = 2 * COMPILER_TIMEOUT


def clear_stale(library: pathlib.Path, locked: bool) -> None:
    """Remove what killed builds left in the cache: this library's temporaries (no other
    build of it can be running while ``locked``) and any build's temporaries older than
    :data:`STALE_AFTER`."""
    now = time.time()
    with contextlib.suppress(OSError):
        for entry in library.parent.iterdir():
            if not entry.name.startswith(".") or not entry.name.endswith((".tmp", ".cc")):
                continue
            own = entry.name.startswith(f".{library.stem}.")
            with contextlib.suppress(OSError):
                if (own and locked) or now - entry.lstat().st_mtime > STALE_AFTER:
                    if entry.is_dir() and not entry.is_symlink():
                        shutil.rmtree(entry, ignore_errors=True)
                    else:
                        entry.unlink()
