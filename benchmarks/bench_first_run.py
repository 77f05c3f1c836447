"""Benchmark of a first run on a new machine: the quick-start solve into an empty cache.

    python benchmarks/bench_first_run.py [--repeats N]

Each run is a fresh process with a cache folder of its own, solving the shipped hanging
gait as the README's quick start does (code generation, gcc, IPOPT, polish and the
independent check). Two ways of compiling are timed alternately:

* **now**: the engine's Jacobians compile in a thread at -O1 while the process compiles
  the rest (the engine's passes at -O3, the verification's map, the NLP at -O1);
* **baseline**: every library at -O3, one after the other, as before the change.

Each line also gives each library's own compile time [s] and size of C [MB], from the
process's own account; the last gives the ratio of the medians. ``--record`` writes the
figure to ``benchmarks/figures/bench_first_run.json`` for the README's speed table.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from figures import Figure, report

#: Run in the child: time each library's compile, optionally as the baseline, then solve.
CHILD = """
import json, sys, time
import baslip.engine.codegen as codegen
builds = []
build = codegen._build
def timed(name, c_text, compiler, library, optimisation):
    start = time.perf_counter()
    build(name, c_text, compiler, library, optimisation)
    builds.append([name, optimisation, len(c_text) / 1e6, time.perf_counter() - start])
codegen._build = timed
if sys.argv[1] == "baseline":
    import baslip.engine.background as background
    import baslip.engine.kernels as kernels
    import baslip.gait.shooting as shooting
    kernels.JACOBIAN_OPTIMISATION = shooting.NLP_OPTIMISATION = "-O3"
    init = background.KernelsLater.__init__
    def at_once(self, *arguments, **keywords):  # compile in the caller, and wait
        init(self, *arguments, **keywords)
        self.get()
    background.KernelsLater.__init__ = at_once
import baslip
result = baslip.solve_problem(baslip.load_problem("downward"))
print(json.dumps({"status": str(result.status), "builds": builds}))
"""


def first_run(how: str) -> tuple[float, dict]:
    """Wall time [s] of one first run, and the child's account of its compiles."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, BASLIP_CACHE_DIR=cache)
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", CHILD, how], env=env, check=True, capture_output=True, text=True)
        wall = time.perf_counter() - start
    return wall, json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=2, help="runs of each way (default 2)")
    parser.add_argument("--record", action="store_true", help="write the figure to benchmarks/figures/")
    args = parser.parse_args()
    walls: dict[str, list[float]] = {"now": [], "baseline": []}
    for _ in range(args.repeats):
        for how in walls:
            wall, account = first_run(how)
            walls[how].append(wall)
            builds = ", ".join(f"{name} {level} {size:.2f} MB {seconds:.1f} s"
                               for name, level, size, seconds in account["builds"])
            print(f"{how:>8}: {wall:5.1f} s ({account['status']}); {builds}", flush=True)
    now, baseline = (statistics.median(walls[how]) for how in ("now", "baseline"))
    print(f"median first run: now {now:.1f} s, baseline {baseline:.1f} s, ratio {baseline / now:.2f}x")
    report("bench_first_run", [Figure(
        22, "first solve on a new machine: the shipped hanging gait into an empty cache (code generation, gcc, "
        "solve)", now, "s", 30.0, "lower",
        f"median of {args.repeats} fresh processes; every library at -O3, one after the other: {baseline:.1f} s "
        f"({baseline / now:.2f}x)")], args.record)


if __name__ == "__main__":
    main()
