"""Running many independent tasks on both cores, resumably, with progress.

* Each finished task becomes one CSV row, appended, flushed and synced at once, so an
  interruption (Ctrl-C, a kill) loses only tasks that were still running.
* On a rerun, rows already in the CSV are skipped: a finished study does no new work. A
  last line cut short by a kill is dropped, and so is a row that cannot be trusted (torn,
  or a converged gait's apex state not finite: changed by hand), each with a note naming
  its line, so that its task runs again; a file that is empty, has a torn or foreign
  header or cannot be decoded is set aside with a message and started afresh; rows with a
  repeated key are dropped (the first is kept) with a message.
* Tasks come in a fixed number of lanes (:data:`LANES` unless a run asks for more,
  whatever the number of cores, and recorded with the results); each lane is run in turn
  by one worker process (one per lane, at most one per core, or fewer with ``jobs``), so
  that each task is warm-started from the one before it in its lane. The state a task hands on (``row["state"]``) is saved beside the CSV
  before its row, and a resumed lane replays the saved states of its finished tasks, so
  every task starts exactly as it would have in an uninterrupted run.
* Workers die with the process that started them, even under ``kill -9``.
* When every task is done the CSV is rewritten in task order and the saved states are
  removed: two complete runs give the same file whatever the interruptions.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from baslip.diagnostics import ROOT_LOGGER, logger
from baslip.engine.codegen import leave_notices_to_parent, note_code, recording_code
from baslip.errors import InputError
from baslip.files.atomic import write_files_atomically, writing
from baslip.files.rows import ends_a_line, row_damage
from baslip.studies.processes import (
    Inbox,
    LaneFailed,
    Reporting,
    WorkerCode,
    WorkerDied,
    start_workers,
    stop_workers,
    worker_count,
)
from baslip.studies.progress import Progress
from baslip.studies.schedulerprobe import scheduler_problem

_log = logger(__name__)

#: Lanes a study's tasks are cut into. Fixed, so that the warm starts (and so the answers)
#: do not depend on the machine; it is recorded with the study.
LANES = 2


@dataclass(frozen=True)
class Workers:
    """Where a study's lanes run. ``jobs``: worker processes (default one per lane, at
    most one per core; fewer run several lanes each, in turn); ``scheduler``: a Dask
    scheduler's address, or ``local`` for a LocalCluster of ``jobs`` workers (default:
    local processes, no Dask). The answers depend on neither."""

    jobs: int | None = None
    scheduler: str | None = None


class ResumableCsv:
    """A CSV file of result rows, keyed by some columns, that can be appended to safely.

    ``rows`` are the rows read and appended so far (cells as strings); ``notes`` are the
    messages about what was repaired when the file was read.
    """

    def __init__(self, path: Path, columns: Sequence[str], key_columns: Sequence[str]):
        self.path, self.columns, self.key_columns = Path(path), list(columns), list(key_columns)
        self.rows: list[dict[str, str]] = []
        self.notes: list[str] = []
        self.states = StateLog(self.path.with_name(f".{self.path.name}.states"))
        if self.path.exists():
            self._load()
        if not self.path.exists():
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._write_text(self._header(), mode="w")

    def _header(self) -> str:
        return ",".join(self.columns) + "\n"

    def _load(self) -> None:
        raw = self.path.read_bytes()
        if raw and not raw.endswith(b"\n"):  # a row cut short by a kill: drop it
            raw = raw[: raw.rfind(b"\n") + 1]
            self.notes.append(f"{self.path.name}: dropped a last row cut short")
        try:
            lines = list(csv.reader(io.StringIO(raw.decode("utf-8"))))
        except (UnicodeDecodeError, csv.Error):
            return self._set_aside("it is not UTF-8 CSV")
        if not lines:  # empty, or only a header cut short
            self.states.clear()
            self._write_text(self._header(), mode="w")
            return
        if lines[0] != self.columns:
            return self._set_aside("its columns are not this study's")
        rows = self._trusted_rows(lines[1:])
        dropped = sum(1 for cells in lines[1:] if cells) - len(rows)
        unique, seen = [], set()
        for row in rows:
            if self.key(row) not in seen:
                seen.add(self.key(row))
                unique.append(row)
        if len(unique) < len(rows):
            self.notes.append(f"{self.path.name}: {len(rows) - len(unique)} rows repeat a key; kept the first of each")
        self.rows = unique
        if len(raw) != self.path.stat().st_size or dropped or len(unique) < len(rows):
            self.rewrite(self.rows)

    def _trusted_rows(self, lines: list[list[str]]) -> list[dict[str, str]]:
        """The rows of ``lines`` (the file's, after its header) that can be trusted; one
        note for each dropped one (see :func:`~baslip.files.rows.row_damage`), whose task
        then runs again."""
        rows = []
        for number, cells in enumerate(lines, start=2):
            damage = row_damage(cells, self.columns) if cells else None
            if damage is not None:
                self.notes.append(f"{self.path.name}: dropped line {number} ({damage}); its task runs again")
            elif cells:
                rows.append(dict(zip(self.columns, cells)))
        return rows

    def _set_aside(self, why: str) -> None:
        aside = self.path.with_name(f"{self.path.name}.set-aside-{time.strftime('%Y%m%dT%H%M%S')}")
        os.replace(self.path, aside)
        self.states.clear()
        self.notes.append(f"{self.path.name}: {why}; moved it to {aside.name} and started afresh")

    def key(self, row: dict) -> tuple[str, ...]:
        return tuple(format_value(row[c]) for c in self.key_columns)

    def done(self) -> set[tuple[str, ...]]:
        return {self.key(row) for row in self.rows}

    def append(self, row: dict) -> None:
        """Append one finished task: its hand-on state first (if any), then its row."""
        if row.get("state") is not None:
            self.states.append(self.key(row), row["state"])
        line = io.StringIO()
        csv.writer(line, lineterminator="\n").writerow([format_value(row.get(c, "")) for c in self.columns])
        self._write_text(line.getvalue(), mode="a")
        self.rows.append({c: format_value(row.get(c, "")) for c in self.columns})

    def rewrite(self, rows: list[dict]) -> None:
        """Replace the file by ``rows`` (atomically)."""
        write_files_atomically({self.path: csv_text(self.columns, rows)})
        self.rows = [{c: format_value(r.get(c, "")) for c in self.columns} for r in rows]

    def keep_tasks(self, tasks: Sequence[dict]) -> str | None:
        """Drop the rows that are no task of ``tasks`` (a row appended by hand, a key from
        another grid), rewriting the file; the note saying so, or None."""
        wanted = {self.key(task) for task in tasks}
        kept = [row for row in self.rows if self.key(row) in wanted]
        if len(kept) == len(self.rows):
            return None
        dropped = len(self.rows) - len(kept)
        self.rows = kept
        self.rewrite(kept)
        note = f"{self.path.name}: dropped {dropped} rows that are no task of this study"
        self.notes.append(note)
        return note

    def finish(self, order: Sequence[dict]) -> None:
        """All tasks done: rewrite the rows in task order and drop the saved states."""
        position = {self.key(task): i for i, task in enumerate(order)}
        self.rewrite(sorted(self.rows, key=lambda r: position.get(self.key(r), len(position))))
        self.states.clear()

    def _write_text(self, text: str, mode: str) -> None:
        with writing(self.path), open(self.path, mode) as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())


class StateLog:
    """Saved hand-on states of finished tasks: one JSON line per task, appended and synced
    (floats round-trip exactly through JSON)."""

    def __init__(self, path: Path):
        self.path = path

    def append(self, key: tuple[str, ...], state) -> None:
        # After a line cut short (a kill, a full disk), start a new one: the torn line is
        # skipped when read, and must not swallow this one.
        with writing(self.path), open(self.path, "a+") as handle:
            torn = handle.tell() > 0 and not ends_a_line(self.path)
            handle.write(("\n" if torn else "") + json.dumps({"key": list(key), "state": state}) + "\n")
            handle.flush()
            os.fsync(handle.fileno())

    def read(self) -> dict[tuple[str, ...], Any]:
        states: dict[tuple[str, ...], Any] = {}
        if not self.path.exists():
            return states
        for line in self.path.read_text(errors="replace").splitlines():
            try:
                entry = json.loads(line)
                states[tuple(entry["key"])] = entry["state"]
            except (ValueError, KeyError, TypeError):
                continue  # a line cut short by a kill: its task is redone
        return states

    def clear(self) -> None:
        self.path.unlink(missing_ok=True)


def csv_text(columns: Sequence[str], rows: Sequence[dict]) -> str:
    """``rows`` as CSV text under the header ``columns`` (cells by :func:`format_value`,
    missing ones empty)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows([[format_value(row.get(c, "")) for c in columns] for row in rows])
    return buffer.getvalue()


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
    """How a run went: tasks in total, already done before, run now, its wall time,
    whether it was interrupted (Ctrl-C), and why a worker ended before finishing its
    lanes ("" if none did)."""

    total: int
    skipped: int
    ran: int
    wall_time_s: float
    interrupted: bool
    worker_failure: str = ""

    @property
    def complete(self) -> bool:
        return not self.interrupted and not self.worker_failure and self.skipped + self.ran == self.total


def run_tasks(
    lanes: Sequence[Sequence[dict]],
    worker: Callable[[list[dict], Any, Any], None],
    context: object,
    table: ResumableCsv,
    label: str,
    quiet: bool = False,
    workers: Workers | None = None,
) -> RunReport:
    """Run the tasks not yet in ``table`` on ``workers`` (:class:`Workers`): one worker
    process per lane by default, at most one per core.

    A lane is an ordered list of tasks that one worker takes in turn. The worker gets
    the whole lane: a task already done is marked ``done`` and carries the ``state`` it
    handed on (None if it handed on nothing), so the worker can replay it instead of
    running it. ``worker(lane, context, queue)`` puts one row per task it ran on the
    queue, and returns (:func:`run_lane` then ends the lane, or says why its function
    raised); a row's ``state`` entry, if not None, is saved for later resumes.
    When all tasks are done the table is put in task order (:meth:`ResumableCsv.finish`).
    """
    note = table.keep_tasks([task for lane in lanes for task in lane])
    if note is not None and not quiet:
        _log.warning(f"note: {note}")
    done, states = table.done(), table.states.read()
    total = sum(len(lane) for lane in lanes)
    marked = [[_marked(task, table.key(task), done, states) for task in lane] for lane in lanes]
    todo = [lane for lane in marked if any(not t.get("done") for t in lane)]
    skipped = total - sum(sum(1 for t in lane if not t.get("done")) for lane in todo)
    start = time.perf_counter()
    ran, interrupted, failure = 0, False, ""
    if todo:
        workers = workers or Workers()
        if workers.scheduler is not None:
            ran, interrupted, failure = run_lanes_on_dask(todo, worker, context, table, label, quiet, skipped, total,
                                                          start, workers.scheduler, workers.jobs)
        else:
            ran, interrupted, failure = _run_lanes(todo, worker, context, table, label, quiet, skipped, total, start,
                                                   workers.jobs)
    report = RunReport(total, skipped, ran, time.perf_counter() - start, interrupted, failure)
    if report.complete:
        table.finish([task for lane in lanes for task in lane])
    return report


def _marked(task: dict, key, done: set, states: dict) -> dict:
    if key not in done:
        return task
    return {**task, "done": True, "state": states.get(key)}


def _run_lanes(todo, worker, context, table, label, quiet, skipped, total, start,
               jobs=None) -> tuple[int, bool, str]:
    """Run the lanes ``todo`` on worker processes, each sending its rows back on a
    pipe of its own. Pipes, not a multiprocessing queue: they need no semaphores, so no
    resource-tracker process is started that could outlive a killed run."""
    count = worker_count(jobs, len(todo))
    shares = [todo[k::count] for k in range(count)]  # lanes dealt out in turn
    progress = Progress(label, total, quiet)
    processes, readers = start_workers(_worker_main, [(worker, share, context) for share in shares])
    inbox = Inbox(readers, processes)
    try:
        return _collect(inbox.next_row, len(todo), table, progress, skipped, start)
    finally:
        stop_workers(processes, inbox)


def _collect(next_row, lanes: int, table, progress, skipped: int, start: float,
             seen: set | None = None) -> tuple[int, bool, str]:
    """Write rows as they come until each of ``lanes`` lanes has ended (with a None);
    return (rows written, interrupted by Ctrl-C?, why a worker ended early or ""). With
    ``seen``, rows whose key is in it (a lane run again) are dropped."""
    finished, ran = 0, 0
    try:
        with progress.running(skipped):
            while finished < lanes:
                row = next_row()
                if isinstance(row, WorkerCode):
                    note_code(row.routes)
                    continue
                if isinstance(row, TaskNote):
                    progress.note(row.text)
                    continue
                if row is None:
                    finished += 1
                    continue
                if isinstance(row, LaneFailed):
                    raise WorkerDied(f"a task failed in its worker: {row.text}")
                if seen is not None:
                    if table.key(row) in seen:
                        continue
                    seen.add(table.key(row))
                table.append(row)
                ran += 1
                progress.update(skipped + ran, ran, time.perf_counter() - start)
    except KeyboardInterrupt:
        progress.interrupted(skipped + ran)
        return ran, True, ""
    except WorkerDied as err:
        progress.interrupted(skipped + ran, str(err))
        return ran, False, str(err)
    progress.close()
    return ran, False, ""


class SchedulerError(InputError):
    """Dask is not installed, or its scheduler cannot be reached."""


#: Times Dask runs a lane again after the worker running it died.
DASK_RETRIES = 3
#: How long to wait for a Dask scheduler to answer.
DASK_CONNECT_TIMEOUT = "10s"


def check_scheduler(scheduler: str) -> None:
    """Raise :class:`SchedulerError` unless Dask is installed and, for an address, its
    scheduler answers (first as a Dask scheduler should, :mod:`~baslip.studies.schedulerprobe`):
    checked before a run creates anything."""
    try:
        from distributed import Client
    except ImportError:
        raise SchedulerError("--scheduler", "needs Dask: pip install 'baslip[dask]'") from None
    if scheduler == "local":
        return
    scheme = scheduler.split("://", 1)[0] if "://" in scheduler else "tcp"
    if scheme != "tcp":
        raise SchedulerError("--scheduler", f"{scheme}:// addresses need a security or transport set-up baslip does "
                             "not make; give tcp://HOST:PORT or local")
    problem = scheduler_problem(scheduler)
    if problem is not None:
        raise SchedulerError("--scheduler", problem)
    try:
        Client(scheduler, timeout=DASK_CONNECT_TIMEOUT).close()
    except (OSError, TimeoutError, ValueError, TypeError) as err:
        raise SchedulerError("--scheduler", f"cannot reach the Dask scheduler at {scheduler}: {str(err).splitlines()[0][:120]}") from None


def run_lanes_on_dask(todo, worker, context, table, label, quiet, skipped, total, start, scheduler: str,
                      jobs: int | None) -> tuple[int, bool, str]:
    """Run each lane as one Dask task on the scheduler at ``scheduler`` (or on a
    LocalCluster of ``jobs`` single-threaded worker processes, for ``local``).

    Lanes stay lanes: a task runs its lane in order, warm starts and replayed states
    included, so the rows are those of a local run. Rows stream back through a Dask
    queue and are written as they come. A lane whose worker dies is run again by Dask
    (up to :data:`DASK_RETRIES` times); rows it repeats are dropped by their key.
    Workers must be able to import baslip; the problem travels with each lane, as data.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise SchedulerError("--scheduler", "needs Dask: pip install 'baslip[dask]'") from None
    cluster = None
    try:
        if scheduler == "local":
            cluster = LocalCluster(n_workers=jobs or worker_count(None, len(todo)), threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
        else:
            client = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError, TypeError) as err:
        raise SchedulerError("--scheduler", f"cannot reach the Dask scheduler at {scheduler}: {err}") from None
    except RuntimeError as err:  # Dask's own worker processes did not start
        raise SchedulerError("--scheduler", f"Dask's LocalCluster could not start its workers ({err}); they import the "
                             "script that started the run, so a script must start it under "
                             "`if __name__ == \"__main__\":`") from None
    # The client closes before its cluster: a client whose scheduler went first keeps
    # trying to reach it, and its attempts end in "Future exception was never retrieved
    # ... TimeoutError" on stderr after the run.
    try:
        with client:
            return _collect_from_dask(client, todo, worker, context, table, Progress(label, total, quiet), skipped,
                                      start)
    finally:
        if cluster is not None:
            cluster.close()


def _collect_from_dask(client, todo, worker, context, table, progress, skipped: int, start: float):
    """Submit each lane of ``todo`` as a Dask task and write the rows they stream back
    through a Dask queue (see :func:`_collect`); cancel what still runs at the end."""
    from distributed import Queue

    queue = Queue(f"baslip-rows-{os.getpid()}-{time.time_ns()}", client=client)
    futures = [client.submit(_lane_on_dask, worker, lane, context, queue, pure=False, retries=DASK_RETRIES)
               for lane in todo]

    def next_row():
        while True:
            try:
                return queue.get(timeout=1.0)
            except TimeoutError:
                failed = [f for f in futures if f.status == "error"]
                if failed:
                    raise WorkerDied(f"a Dask task failed: {failed[0].exception()}") from None

    try:
        return _collect(next_row, len(todo), table, progress, skipped, start, seen=table.done())
    finally:
        client.cancel(futures)


def _lane_on_dask(worker, lane, context, queue) -> None:
    """A Dask task: one lane, rows onto the Dask queue, then its end (:func:`run_lane`)."""
    leave_notices_to_parent()
    with recording_code() as used:
        run_lane(worker, lane, context, Reporting(queue.put, used))


def _worker_main(worker, lanes, context, connection) -> None:
    """A worker process's work, once it has asked to die with its parent: leave Ctrl-C and
    the fallback notices to the parent, run its lanes in turn, report what ran."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops the workers itself
    leave_notices_to_parent()
    send = _one_at_a_time(connection.send)  # rows from this thread, notes from heartbeats' threads
    relay_notes(send)
    with recording_code() as used:
        for lane in lanes:
            if not run_lane(worker, lane, context, Reporting(send, used)):
                return  # the parent stops the run: the other lanes would not be written


def run_lane(worker, lane: list[dict], context, reporting: Reporting) -> bool:
    """Run one lane, then send its end: None, or why its function raised
    (:class:`LaneFailed`, in one line; no traceback in the worker's stderr). Whether it
    ran through."""
    try:
        worker(lane, context, reporting)
    except Exception as err:  # noqa: BLE001 -- any failure of a task is the run's, told to the parent
        reporting.end(f"{type(err).__name__}: {str(err).splitlines()[0] if str(err) else 'no message'}")
        return False
    reporting.end()
    return True


def _one_at_a_time(send: Callable[[object], None]) -> Callable[[object], None]:
    """``send`` behind a lock: two threads' messages never interleave on the pipe."""
    lock = threading.Lock()

    def locked(item: object) -> None:
        with lock:
            send(item)

    return locked


@dataclass(frozen=True)
class TaskNote:
    """A progress line from inside a worker's task (an IPOPT try that still runs, an
    atlas cell's stage), sent to the parent, whose progress line shows the latest."""

    text: str


class _NoteRelay(logging.Handler):
    """In a worker: baslip's INFO records go to the parent as :class:`TaskNote`; warnings
    are written here, as they would be with no handler at all."""

    def __init__(self, send: Callable[[object], None]):
        super().__init__(logging.INFO)
        self._send = send

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING:
            if logging.lastResort is not None:
                logging.lastResort.handle(record)
            return
        try:
            self._send(TaskNote(record.getMessage()))
        except Exception:  # logging's own convention: a failing handler reports, never raises
            self.handleError(record)


def relay_notes(send: Callable[[object], None]) -> None:
    """In a worker process: send baslip's progress records to the parent with ``send``
    (the worker's own stderr is the parent's, but its lines would cut across the parent's
    progress bar), so that what a long task is doing shows in the parent's progress."""
    base = logging.getLogger(ROOT_LOGGER)
    base.addHandler(_NoteRelay(send))
    base.setLevel(logging.INFO)


def split_lanes(tasks: Sequence[dict], n: int = LANES) -> list[list[dict]]:
    """``n`` contiguous lanes of nearly equal length, in order."""
    size = -(-len(tasks) // n) if tasks else 1
    return [list(tasks[i : i + size]) for i in range(0, len(tasks), size)]
