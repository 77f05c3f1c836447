"""Running many independent tasks on both cores, resumably, with progress.

* Each finished task becomes one CSV row, appended, flushed and synced at once, so an
  interruption (Ctrl-C, a kill) loses only tasks that were still running.
* On a rerun, rows already in the CSV are skipped: a finished study does no new work. A
  last line cut short by a kill is dropped before appending.
* Tasks come in lanes, one per worker process, so that each worker can warm-start a task
  from the one before it in its lane.
"""

from __future__ import annotations

import csv
import io
import multiprocessing
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

#: Number of worker processes (the machines this runs on have two cores).
WORKERS = min(2, os.cpu_count() or 1)


class ResumableCsv:
    """A CSV file of result rows, keyed by some columns, that can be appended to safely."""

    def __init__(self, path: Path, columns: Sequence[str], key_columns: Sequence[str]):
        self.path, self.columns, self.key_columns = Path(path), list(columns), list(key_columns)
        self.rows: list[dict[str, str]] = []
        if self.path.exists():
            self._load()
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._write_text(",".join(self.columns) + "\n", mode="w")

    def _load(self) -> None:
        raw = self.path.read_bytes()
        if raw and not raw.endswith(b"\n"):  # a row cut short by a kill: drop it
            raw = raw[: raw.rfind(b"\n") + 1]
            with open(self.path, "r+b") as handle:
                handle.truncate(len(raw))
        reader = csv.DictReader(io.StringIO(raw.decode()))
        if reader.fieldnames != self.columns:
            raise ValueError(f"{self.path} has columns {reader.fieldnames}, expected {self.columns}; move it away to start afresh")
        self.rows = list(reader)

    def key(self, row: dict) -> tuple[str, ...]:
        return tuple(format_value(row[c]) for c in self.key_columns)

    def done(self) -> set[tuple[str, ...]]:
        return {self.key(row) for row in self.rows}

    def append(self, row: dict) -> None:
        line = io.StringIO()
        csv.writer(line, lineterminator="\n").writerow([format_value(row.get(c, "")) for c in self.columns])
        self._write_text(line.getvalue(), mode="a")
        self.rows.append({c: format_value(row.get(c, "")) for c in self.columns})

    def _write_text(self, text: str, mode: str) -> None:
        with open(self.path, mode) as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())


def format_value(value) -> str:
    """A CSV cell: floats with full precision (task values come pre-rounded, so keys
    compare equal across runs), booleans as true/false, None as empty."""
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, np.integer):
        return str(int(value))
    return str(value)


@dataclass(frozen=True)
class RunReport:
    """How a run went: tasks in total, already done before, run now, and its wall time."""

    total: int
    skipped: int
    ran: int
    wall_time_s: float
    interrupted: bool


def run_tasks(
    lanes: Sequence[Sequence[dict]],
    worker: Callable[[list[dict], object, "multiprocessing.Queue"], None],
    context: object,
    table: ResumableCsv,
    label: str,
    quiet: bool = False,
) -> RunReport:
    """Run the tasks not yet in ``table``, one worker process per lane.

    A lane is an ordered list of tasks that one worker takes in turn (so it can warm-start
    each from the one before). ``worker(lane, context, queue)`` puts one row per task, and
    then None, on the queue.
    """
    done = table.done()
    total = sum(len(lane) for lane in lanes)
    todo = [[t for t in lane if table.key(t) not in done] for lane in lanes]
    todo = [lane for lane in todo if lane]
    skipped = total - sum(len(lane) for lane in todo)
    start = time.perf_counter()
    if not todo:
        return RunReport(total, skipped, 0, 0.0, False)
    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    processes = [ctx.Process(target=worker, args=(lane, context, queue), daemon=True) for lane in todo]
    for process in processes:
        process.start()
    finished, ran = 0, 0
    try:
        while finished < len(processes):
            row = queue.get()
            if row is None:
                finished += 1
                continue
            table.append(row)
            ran += 1
            if not quiet:
                _progress(label, skipped + ran, total, ran, time.perf_counter() - start)
    except KeyboardInterrupt:
        for process in processes:
            process.terminate()
        if not quiet:
            print(f"\n{label}: interrupted; {skipped + ran} of {total} rows are saved", file=sys.stderr)
        return RunReport(total, skipped, ran, time.perf_counter() - start, True)
    for process in processes:
        process.join()
    if not quiet:
        print(file=sys.stderr)
    return RunReport(total, skipped, ran, time.perf_counter() - start, False)


def split_lanes(tasks: Sequence[dict], n: int = WORKERS) -> list[list[dict]]:
    """``n`` contiguous lanes of nearly equal length, in order."""
    size = -(-len(tasks) // n) if tasks else 1
    return [list(tasks[i : i + size]) for i in range(0, len(tasks), size)]


def _progress(label: str, done: int, total: int, ran: int, elapsed: float) -> None:
    rate = ran / elapsed if elapsed > 0 else 0.0
    eta = (total - done) / rate if rate > 0 else float("inf")
    print(f"\r{label}: {done}/{total} done, {rate:.2f}/s, about {eta:.0f} s left   ", end="", file=sys.stderr, flush=True)
