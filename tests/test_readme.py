"""Specification of the README's Python: it runs as a new user runs it.

* The README's ```` ```python ```` blocks, read from README.md and run verbatim in a fresh
  working folder, succeed from a script without an ``if __name__ == "__main__":`` guard,
  from ``python -c`` and from standard input: the gait converges, the sweep solves its
  nine points in memory and writes ``runs/small_grid`` as ``baslip solve`` does, the
  return map takes its strides.
* No process the run started outlives it: every descendant seen while it ran, its
  worker processes among them, is gone once it has returned.
* The blocks run are the README's blocks: a block added or changed in the README is a
  block these tests must be told of.
"""

import hashlib
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from processes import descendants, gone

from baslip.children import WORKER_OF

ROOT = Path(__file__).resolve().parents[1]

#: The README's Python blocks, in order: what each shows, and the SHA-256 of its text.
#: A block added to or changed in the README fails :func:`test_the_blocks_run_are_the_readmes`
#: until it is listed here (and so run by the tests below).
BLOCKS = [
    ("a gait, its numbers, figures and animation; a sweep in memory and into a folder",
     "2e1dce517927d517834a668ffa205f8dc2607dc74d696f1d8fa41c7fe978c58d"),
    ("the compiled return map: a stride, its Jacobians, a simulation",
     "b64688c7d962eabec1124d3a5feffdfde5c7f9ef7d1518b84d928d6583496c87"),
]

#: Appended to the blocks: what they computed, as one JSON line for the test to read.
REPORT = """
import json as _json
print("README-RESULTS", _json.dumps({
    "status": str(gait.status), "points": len(grid.to_dataframe()), "written": sorted(p.name for p in
    __import__("pathlib").Path("runs/small_grid").iterdir()), "gif": __import__("os").path.getsize("gait.gif"),
    "strides": len(run.apexes), "fall": None if stride.fall is None else str(stride.fall)}))
"""

#: Seconds a process may take to disappear once the run has returned.
GRACE_S = 2.0


def readme_blocks() -> list[str]:
    """The text of each ```` ```python ```` block of README.md, in order."""
    return re.findall(r"^```python\n(.*?)^```$", (ROOT / "README.md").read_text(), flags=re.M | re.S)


def digest(block: str) -> str:
    return hashlib.sha256(block.encode()).hexdigest()


def test_the_blocks_run_are_the_readmes():
    assert [digest(block) for block in readme_blocks()] == [sha for _, sha in BLOCKS]


class ProcessWatch:
    """The descendants of a process, collected every tenth of a second while it runs, and
    among them those that baslip started as workers (marked in their environment)."""

    def __init__(self, process: subprocess.Popen):
        self.process, self.seen, self.workers = process, set(), set()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()

    def _watch(self):
        while self.process.poll() is None:
            for pid in descendants(self.process.pid) - self.seen:
                self.seen.add(pid)
                if marked_worker_of(pid) == self.process.pid:
                    self.workers.add(pid)
            time.sleep(0.1)

    def outliving(self) -> list[int]:
        """The processes seen, or marked as its workers anywhere, alive after the run."""
        self._thread.join()
        deadline = time.monotonic() + GRACE_S
        while time.monotonic() < deadline and not all(gone(pid) for pid in self.seen | all_workers_of(self.process.pid)):
            time.sleep(0.05)
        return sorted(pid for pid in self.seen | all_workers_of(self.process.pid) if not gone(pid))


def marked_worker_of(pid: int) -> int | None:
    """The parent pid named in process ``pid``'s environment, if baslip started it as a worker."""
    try:
        with open(f"/proc/{pid}/environ", "rb") as handle:
            entries = handle.read().split(b"\0")
    except OSError:
        return None
    prefix = f"{WORKER_OF}=".encode()
    return next((int(entry[len(prefix):]) for entry in entries if entry.startswith(prefix)), None)


def all_workers_of(parent: int) -> set[int]:
    """Every living process marked as a worker of ``parent``, wherever it now hangs."""
    return {int(entry) for entry in os.listdir("/proc") if entry.isdigit() and marked_worker_of(int(entry)) == parent}


def launch(mode: str, program: str, folder: Path) -> tuple[subprocess.Popen, str | None]:
    """Start ``program`` in ``folder`` as a script file, through ``-c`` or on standard
    input; return the process and what is to be written on its standard input."""
    command, given = {"script": ([sys.executable, "tour.py"], None), "-c": ([sys.executable, "-c", program], None),
                      "stdin": ([sys.executable, "-"], program)}[mode]
    if mode == "script":
        (folder / "tour.py").write_text(program)
    process = subprocess.Popen(command, cwd=folder, stdin=subprocess.PIPE if given else subprocess.DEVNULL,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return process, given


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc to watch processes")
@pytest.mark.parametrize("mode", ["script", "-c", "stdin"])
def test_the_readme_python_runs_verbatim_and_leaves_no_process(mode, tmp_path):
    program = "\n".join(readme_blocks()) + REPORT
    assert "__main__" not in program  # no guard: the workers must not need one
    run, given = launch(mode, program, tmp_path)
    watch = ProcessWatch(run)
    stdout, stderr = run.communicate(given, timeout=600)
    assert run.returncode == 0, stderr[-3000:]
    assert watch.outliving() == []
    assert len(watch.workers) >= 2  # the sweeps ran on worker processes, which are gone
    results = json.loads(stdout.split("README-RESULTS", 1)[1])
    assert results["status"] == "converged"
    assert results["points"] == 9
    assert {"points.csv", "result.json"} <= set(results["written"])
    assert results["gif"] > 0
    assert results["strides"] >= 1 and results["fall"] is None
