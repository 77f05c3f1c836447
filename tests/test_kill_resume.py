"""Specification of resumes, for every study kind: a run killed at any moment and run
again ends with the rows of an uninterrupted run.

For each kind (sweep, random sample, basin, optimal, adaptive, atlas, controllers,
continuation and curve; :mod:`killcases`) a small study is run uninterrupted, twice, and
the two runs must write the same tables. Then
it is started and sent SIGKILL at 20 moments drawn (seeded) uniformly over the
uninterrupted run's wall time (dealt between two chains that run side by side), each
start resuming the folder the last one left. When a resumed start finishes before its
moment, the round is over and the moment goes to a fresh folder (a moment later than a
whole run is no kill). After every round:

* each table holds exactly the uninterrupted run's rows, timing columns aside, in the
  same order: no row repeated, none missing, none different;
* nothing is left to resume (no saved states) and ``result.json`` says complete.

Continuation and curve runs write their files once, at the end, so a killed one starts
again: for them this checks that a kill never leaves a folder that a rerun refuses or
finishes differently.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from killcases import CASES, ROOT, KillCase

#: Kills per study kind.
KILLS = 20
#: Kill chains run side by side.
CHAINS = 2
#: Longest a small study may take to finish once started (it takes seconds).
FINISH_TIMEOUT_S = 600

pytestmark = pytest.mark.skipif(not os.path.isdir("/proc"), reason="kills runs")


def start(problem: Path, out: Path, output=subprocess.DEVNULL) -> subprocess.Popen:
    # One worker process a run (the answers follow the lanes, not the workers): the two
    # chains' starts then share the two cores without waiting on each other's imports.
    return subprocess.Popen([sys.executable, "-m", "baslip.solve", str(problem), "--out", str(out), "--quiet",
                             "--jobs", "1"], cwd=ROOT, stdout=output, stderr=output, text=True)


def finish(problem: Path, out: Path) -> float:
    """Run to the end; the wall time in seconds."""
    began = time.monotonic()
    run = start(problem, out, subprocess.PIPE)
    _, err = run.communicate(timeout=FINISH_TIMEOUT_S)
    assert run.returncode == 0, err
    return time.monotonic() - began


def rows(out: Path, name: str, timing: tuple[str, ...]) -> list[list[str]]:
    """The table ``name`` of ``out``, header included, without its ``timing`` columns."""
    with open(out / name, newline="") as handle:
        table = list(csv.reader(handle))
    kept = [i for i, column in enumerate(table[0]) if column not in timing]
    return [[row[i] for i in kept] for row in table]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> tuple[Path, dict[str, float]]:
    """Every case run without interruption (sources first), twice: the second run, into
    a fresh folder, must write the same tables, and its wall time (caches warm, as for
    the starts that follow) scales the moments."""
    folder = tmp_path_factory.mktemp("uninterrupted")
    walls = {}
    for case in CASES:
        problem = folder / f"{case.name}.yaml"
        problem.write_text(case.text)
        finish(problem, folder / case.name)
        again = folder / "again" / case.name
        again.parent.mkdir(exist_ok=True)
        for source in case.sources:
            if not (again.parent / source).exists():
                shutil.copytree(folder / source, again.parent / source)
        walls[case.name] = finish(problem, again)
        for table in case.tables:
            assert rows(again, table, case.timing) == rows(folder / case.name, table, case.timing), (case.name, table)
    return folder, walls


def new_round(case: KillCase, references: Path, folder: Path) -> tuple[Path, Path]:
    """A folder with the case's problem and finished copies of its sources; the problem
    file and the output folder."""
    folder.mkdir(parents=True)
    for source in case.sources:
        shutil.copytree(references / source, folder / source)
    problem = folder / f"{case.name}.yaml"
    problem.write_text(case.text)
    return problem, folder / case.name


def killed(problem: Path, out: Path, moment_s: float) -> bool:
    """Start a run and SIGKILL it ``moment_s`` seconds later; False if it ended first."""
    run = start(problem, out)
    try:
        run.wait(timeout=moment_s)
    except subprocess.TimeoutExpired:
        run.send_signal(signal.SIGKILL)
        run.wait()
        return True
    assert run.returncode == 0
    return False


def assert_same_as_uninterrupted(case: KillCase, out: Path, reference: Path) -> None:
    for table in case.tables:
        got, want = rows(out, table, case.timing), rows(reference, table, case.timing)
        assert got == want, f"{table} differs from the uninterrupted run's"
    assert not [p.name for p in out.iterdir() if p.name.endswith(".states")]
    # (adaptive and continuation runs, which end in one step, record no "complete")
    assert json.loads((out / "result.json").read_text()).get("complete", True) is True


def kill_chain(case: KillCase, references: Path, moments, folder: Path) -> int:
    """Kill runs of ``case`` at ``moments`` (seconds after each start), resuming each
    time, in rounds (see the module's docstring); check each finished round against the
    uninterrupted run. Returns how many kills landed in a running study."""
    rounds, used, landed = 0, 0, 0
    while used < len(moments):
        problem, out = new_round(case, references, folder / f"round{rounds}")
        rounds += 1
        first = True
        while used < len(moments) and killed(problem, out, moments[used]):
            used, landed, first = used + 1, landed + 1, False
        if used < len(moments) and first:  # a moment after the end of a whole run: no kill
            used += 1
        elif used == len(moments):
            finish(problem, out)
        # else a resumed start finished before its moment: a fresh round takes the moment
        assert_same_as_uninterrupted(case, out, references / case.name)
    return landed


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
def test_killed_at_20_random_moments_every_resume_ends_with_the_uninterrupted_rows(case, uninterrupted, tmp_path):
    references, walls = uninterrupted
    moments = np.random.default_rng(zlib.crc32(case.name.encode())).uniform(0.0, walls[case.name], KILLS)
    # Two chains at once, one per core: a start spends most of its time importing.
    with ThreadPoolExecutor(CHAINS) as pool:
        landed = sum(pool.map(lambda k: kill_chain(case, references, moments[k::CHAINS], tmp_path / f"chain{k}"),
                              range(CHAINS)))
    assert landed >= KILLS // 2, f"only {landed} of {KILLS} kills landed in a running study"
