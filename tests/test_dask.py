"""Studies on a Dask cluster (baslip.studies.runner.run_lanes_on_dask): the same rows as a
local run, even when a worker is killed halfway and its lane is run again, or the run
itself is killed and resumed."""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from runs import ROOT  # noqa: E402

from baslip.problem.reader import load_problem  # noqa: E402
from baslip.studies.registry import run_study  # noqa: E402

GRID = "vary: {ydot: [0.3, 0.6, 0.1], z: [0.35, 0.5, 0.05]}"  # 16 points, 8 per lane


def small_grid(tmp_path):
    text = (ROOT / "problems" / "grid_downward.yaml").read_text().replace(
        "vary: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.05]}", GRID)
    path = tmp_path / "grid.yaml"
    path.write_text(text)
    return path


def rows_of(folder):
    with open(folder / "points.csv", newline="") as handle:
        return [{k: v for k, v in row.items() if k != "time_s"} for row in csv.DictReader(handle)]


@pytest.fixture(scope="module")
def local_rows(tmp_path_factory):
    folder = tmp_path_factory.mktemp("local")
    path = small_grid(folder)
    summary = run_study(load_problem(path), folder / "out", quiet=True)
    assert summary["points"] == 16
    return rows_of(folder / "out")


def test_a_local_cluster_gives_the_rows_of_a_local_run(tmp_path, local_rows):
    path = small_grid(tmp_path)
    summary = run_study(load_problem(path), tmp_path / "out", quiet=True, jobs=2, scheduler="local")
    assert summary["complete"] and summary["points"] == 16
    assert rows_of(tmp_path / "out") == local_rows


def test_a_killed_worker_has_its_lane_run_again(tmp_path, local_rows):
    """The study runs through the command line on a cluster this test holds; once rows
    come in, one worker busy with a lane is killed. Dask runs that lane again on a new
    worker, the repeated rows are dropped, and the file equals the local run's."""
    path = small_grid(tmp_path)
    out = tmp_path / "out"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        pids = client.run(os.getpid)
        run = subprocess.Popen([sys.executable, "-m", "baslip.solve", str(path), "--out", str(out), "--quiet",
                                "--scheduler", cluster.scheduler_address], stderr=subprocess.PIPE, text=True)
        deadline, busy = time.monotonic() + 300, {}
        while time.monotonic() < deadline and not busy and run.poll() is None:  # a row is in, a lane still runs
            written = (out / "points.csv").read_text().count("\n") - 1 if (out / "points.csv").exists() else 0
            busy = {w: tasks for w, tasks in client.processing().items() if tasks} if written >= 1 else {}
            time.sleep(0.05)
        assert busy, "no lane was running to kill"
        os.kill(pids[next(iter(busy))], signal.SIGKILL)
        assert run.wait(timeout=600) == 0, run.stderr.read()
    summary = json.loads((out / "result.json").read_text())
    assert summary["complete"] and summary["points"] == 16
    assert rows_of(out) == local_rows


def test_an_unreachable_scheduler_is_one_line_and_exit_2(tmp_path):
    path = small_grid(tmp_path)
    done = subprocess.run([sys.executable, "-m", "baslip.solve", str(path), "--out", str(tmp_path / "out"),
                           "--scheduler", "tcp://127.0.0.1:9"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("error: --scheduler: cannot reach")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("address", ["tls://127.0.0.1:9", "ucx://127.0.0.1:9"])
def test_a_scheduler_address_baslip_cannot_set_up_is_one_line_and_exit_2(tmp_path, address):
    path = small_grid(tmp_path)
    done = subprocess.run([sys.executable, "-m", "baslip.solve", str(path), "--out", str(tmp_path / "out"),
                           "--scheduler", address], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr[-500:]
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("error: --scheduler: ")
    assert "tcp://HOST:PORT" in done.stderr and not (tmp_path / "out").exists()


def test_a_run_killed_on_a_cluster_resumes_to_the_same_rows(tmp_path, local_rows):
    """The command is killed (SIGKILL) after some rows; run again on the same cluster, it
    replays the saved states of its lanes and finishes with the rows of a local run."""
    path = small_grid(tmp_path)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "baslip.solve", str(path), "--out", str(out), "--quiet", "--scheduler"]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        first = subprocess.Popen(command + [cluster.scheduler_address], stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and first.poll() is None:
            if (out / "points.csv").exists() and (out / "points.csv").read_text().count("\n") - 1 >= 3:
                break
            time.sleep(0.02)
        first.kill()
        first.wait()
        cut = (out / "points.csv").read_text().count("\n") - 1
        assert 0 < cut < 16, "the first run was not cut halfway"
        second = subprocess.run(command + [cluster.scheduler_address], capture_output=True, text=True, timeout=600)
        assert second.returncode == 0, second.stderr
    summary = json.loads((out / "result.json").read_text())
    assert summary["complete"] and summary["done_before_this_run"] == cut
    assert rows_of(out) == local_rows


def test_a_run_on_its_own_local_cluster_killed_at_random_moments_resumes_quietly_to_the_same_rows(tmp_path, local_rows):
    """``--scheduler local`` killed (SIGKILL) at six seeded moments over a run's length,
    each time resumed: the last run ends with the rows of a local run and, quiet, writes
    nothing on stderr (once a client outlived its cluster and left a TimeoutError there)."""
    path = small_grid(tmp_path)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "baslip.solve", str(path), "--out", str(out), "--quiet", "--scheduler", "local"]
    for moment in np.random.default_rng(57).uniform(0.5, 5.0, 6):
        run = subprocess.Popen(command, stderr=subprocess.DEVNULL)
        try:
            run.wait(timeout=moment)
        except subprocess.TimeoutExpired:
            run.kill()
            run.wait()
    last = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert last.returncode == 0 and last.stderr == "", last.stderr
    assert json.loads((out / "result.json").read_text())["complete"]
    assert rows_of(out) == local_rows


UNGUARDED = """
import sys
import baslip
from baslip.errors import InputError

try:
    baslip.run(sys.argv[1], scheduler="local", jobs=1, progress=False)
except InputError as err:
    print("InputError:", err, flush=True)
    sys.exit(3)
"""


def test_a_local_cluster_started_by_a_script_without_a_main_guard_says_it_needs_one(tmp_path):
    """Dask's LocalCluster, unlike baslip's own workers, starts its processes with
    multiprocessing's spawn, which imports the script: without the guard the run is
    refused with an InputError that names the guard, not only Dask's traceback."""
    path = small_grid(tmp_path)
    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED)
    done = subprocess.run([sys.executable, str(script), str(path)], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path)
    assert done.returncode == 3, done.stderr[-2000:]
    assert "--scheduler: Dask's LocalCluster could not start its workers" in done.stdout
    assert 'start it under `if __name__ == "__main__":`' in done.stdout


@pytest.fixture
def web_server():
    """A throwaway HTTP server on 127.0.0.1 (a free port), stopped afterwards."""
    import http.server
    import threading

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_a_scheduler_address_that_is_a_web_server_is_one_line_and_exit_2(tmp_path, web_server):
    """Issue 57: Dask's client read the server's "HTTP/1.0 400" as a message length and
    tried to allocate 3.07 EiB."""
    path = small_grid(tmp_path)
    done = subprocess.run([sys.executable, "-m", "baslip.solve", str(path), "--out", str(tmp_path / "out"),
                           "--scheduler", web_server], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr[-500:]
    assert done.stderr == f"error: --scheduler: {web_server} is no Dask scheduler: nothing answered within 5 s\n"
    assert not (tmp_path / "out").exists()
