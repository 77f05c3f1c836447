"""One writer per output folder.

A run holds an exclusive lock on ``<folder>/.baslip.lock`` for as long as it writes there;
the file names the process (pid, host and command line) so that a second run can say who
holds the folder. The lock is the kernel's (``flock``): it goes with the process that took
it, ``kill -9`` included, so a lock file left behind by a dead process is simply taken
over. The file is removed when the lock is released.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import sys
import tempfile
import time
from pathlib import Path

from baslip.errors import InputError
from baslip.files.atomic import writing
from baslip.problem.text import clip

LOCK_NAME = ".baslip.lock"


class FolderBusy(InputError):
    """Another process is writing into the folder."""


def _holder(handle, attempts: int = 20) -> str:
    """The holder's description; it writes it just after locking, so wait a moment."""
    for _ in range(attempts):
        handle.seek(0)
        text = handle.read(400).strip()
        if text:
            return clip(text, 120)
        time.sleep(0.025)
    return "an unknown process"


@contextlib.contextmanager
def hold(folder: Path):
    """Hold ``folder`` for writing (creating it); raise :class:`FolderBusy` naming the
    holder if another process holds it."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    while True:
        handle = _open_lock(path, folder)
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(handle)
            handle.close()
            raise FolderBusy("", f"output folder {folder} is in use by {holder}; wait for it or choose another --out") from None
        # The previous holder may have removed the file between our open and our lock:
        # then we hold a lock on a deleted file, and must lock the file now at the path.
        try:
            current = os.stat(path)
        except FileNotFoundError:
            handle.close()
            continue
        if (current.st_dev, current.st_ino) == (os.fstat(handle.fileno()).st_dev, os.fstat(handle.fileno()).st_ino):
            break
        handle.close()
    try:
        handle.seek(0)
        handle.truncate()
        command = " ".join(Path(sys.argv[0]).name if i == 0 else a for i, a in enumerate(sys.argv))
        with writing(path):
            handle.write(f"process {os.getpid()} on {os.uname().nodename} ({command})\n")
            handle.flush()
        yield
    finally:
        with contextlib.suppress(OSError):
            path.unlink()
        handle.close()


def _open_lock(path: Path, folder: Path):
    """The lock file, opened for reading and appending; never through a link, which would
    have us truncate whatever file it points to."""
    try:
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW, 0o644)
    except OSError as err:
        if path.is_symlink():
            raise FolderBusy("", f"output folder {folder} has a link at {LOCK_NAME}; remove it, or choose "
                             "another --out") from None
        raise FolderBusy("", f"output folder {folder}: cannot open {LOCK_NAME}: {err.strerror or err}") from None
    return os.fdopen(descriptor, "a+")


def unwritable(folder: Path) -> str | None:
    """Why nothing can be written into ``folder`` (creating it if need be), or None if it
    can: checked before a run or a command does any work."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        return err.strerror or str(err)
    return None


def busy(folder: Path) -> str | None:
    """Who holds ``folder`` for writing, or None if nobody does (checked, not held)."""
    path = folder / LOCK_NAME
    try:
        handle = os.fdopen(os.open(path, os.O_RDONLY | os.O_NOFOLLOW))
    except OSError:
        return None
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _holder(handle)
        fcntl.flock(handle, fcntl.LOCK_UN)
    return None
