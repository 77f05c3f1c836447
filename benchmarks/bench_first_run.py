"""Benchmark of a first run on a new machine, and of the runs after it, as a new user sees them.

    python benchmarks/bench_first_run.py [--repeats N] [--warm M] [--record]

Each run is a fresh process, ``python -m baslip.solve downward --out <folder>``, the
README's quick start:

* **cold**: into an empty cache of its own (``BASLIP_CACHE_DIR``): code generation, gcc,
  IPOPT, polish, the independent check, the multipliers and ``result.json``;
* **warm**: the same command again with that cache filled (the libraries the cold run
  compiled), ``--warm`` times after each cold run.

Each is measured as CPU time (user + sys of the process and of everything it waited for,
gcc included: ``resource.getrusage(RUSAGE_CHILDREN)``) and as wall time. The figures are the
medians, beside issue 56's targets: cold <= 20 s of CPU and <= 30 s wall, warm <= 0.4 s of
CPU. Python's own bytecode is written once before any timing (``import baslip.cli.solve``
with bytecode writing on), as an installation does. Each cold line also gives the run's
``solver.compile_s`` and ``solver.time_s`` (``result.json``) and the libraries it left in
the cache. ``--record`` writes the figures to ``benchmarks/figures/bench_first_run.json``
for the README's speed table (``python benchmarks/speed_table.py`` renders it). Run it on
an idle machine: the figures are CPU and wall times.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time

from figures import Figure, report

#: The quick start's command, after ``python``.
COMMAND = ["-m", "baslip.solve", "downward", "--out"]
#: Issue 56's targets [s].
COLD_CPU_TARGET, COLD_WALL_TARGET, WARM_CPU_TARGET = 20.0, 30.0, 0.4


def _environment(cache: pathlib.Path) -> dict[str, str]:
    """This process's environment with ``cache`` as the compiled-code cache, compiling on,
    and Python free to keep bytecode (as an installed package has it)."""
    env = {k: v for k, v in os.environ.items() if k not in ("BASLIP_NO_COMPILE", "PYTHONDONTWRITEBYTECODE")}
    return env | {"BASLIP_CACHE_DIR": str(cache)}


def timed(arguments: list[str], env: dict[str, str]) -> tuple[float, float]:
    """(CPU time [s], wall time [s]) of ``python arguments`` as a fresh process: user + sys
    of it and of every process it waited for (gcc)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, *arguments], env=env, check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, wall


def solver_times(out: pathlib.Path) -> tuple[float, float]:
    """(``solver.compile_s``, ``solver.time_s``) of the result the run wrote [s]."""
    solver = json.loads((out / "result.json").read_text())["solver"]
    return solver.get("compile_s", float("nan")), solver["time_s"]


def one_round(warm_runs: int) -> tuple[tuple[float, float], list[tuple[float, float]], str]:
    """A cold run into an empty cache, then ``warm_runs`` warm ones: their (CPU, wall) [s],
    and a line on the cold run."""
    with tempfile.TemporaryDirectory() as folder:
        root = pathlib.Path(folder)
        env = _environment(root / "cache")
        cold = timed([*COMMAND, str(root / "cold")], env)
        compile_s, solve_s = solver_times(root / "cold")
        built = sorted(p.name.split("-")[0] for p in (root / "cache").glob("*.so"))
        warm = [timed([*COMMAND, str(root / f"warm{k}")], env) for k in range(warm_runs)]
    line = (f"cold: {cold[0]:5.1f} s CPU, {cold[1]:5.1f} s wall (compile_s {compile_s:.1f} s, time_s {solve_s:.2f} s;"
            f" compiled {', '.join(built)}); warm: " + ", ".join(f"{cpu:.2f} s CPU / {wall:.2f} s wall" for cpu, wall in warm))
    return cold, warm, line


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=2, help="cold runs, each into an empty cache (default 2)")
    parser.add_argument("--warm", type=int, default=5, help="warm runs after each cold run (default 5)")
    parser.add_argument("--record", action="store_true", help="write the figures to benchmarks/figures/")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:  # bytecode, as an installation writes it
        subprocess.run([sys.executable, "-c", "import baslip.cli.solve"], env=_environment(pathlib.Path(scratch)),
                       check=True)
        imports = timed(["-c", "import numpy, casadi"], _environment(pathlib.Path(scratch)))[0]
    colds, warms = [], []
    for _ in range(args.repeats):
        cold, warm, line = one_round(args.warm)
        colds.append(cold)
        warms += warm
        print(line, flush=True)
    cold_cpu, cold_wall = (statistics.median(run[k] for run in colds) for k in (0, 1))
    warm_cpu, warm_wall = (statistics.median(run[k] for run in warms) for k in (0, 1))
    quick_start = "`python -m baslip.solve downward --out DIR` (the README's quick start)"
    report("bench_first_run", [
        Figure(56, f"first run on a new machine: {quick_start} into an empty cache, CPU time with gcc's (user + sys)",
               cold_cpu, "s", COLD_CPU_TARGET, "lower",
               f"median of {args.repeats} fresh processes, each into an empty cache; wall time {cold_wall:.1f} s"),
        Figure(56, f"first run on a new machine: {quick_start} into an empty cache, wall time", cold_wall, "s",
               COLD_WALL_TARGET, "lower", f"median of {args.repeats} fresh processes; CPU time {cold_cpu:.1f} s"),
        Figure(56, f"a run after it: {quick_start} with the cache it filled, CPU time of the whole process (user + sys)",
               warm_cpu, "s", WARM_CPU_TARGET, "lower",
               f"median of {len(warms)} fresh processes; wall time {warm_wall:.2f} s; "
               f"`python -c 'import numpy, casadi'` alone: {imports:.2f} s CPU"),
    ], args.record)


if __name__ == "__main__":
    main()
