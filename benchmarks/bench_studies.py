"""Benchmark of whole studies, run as a user runs them: what ``make studies`` waits for.

    python benchmarks/bench_studies.py [--group other|atlas|all] [--record]

Runs shipped studies one after the other, each as ``python -m baslip.solve
problems/NAME.yaml --out DIR`` into a fresh temporary folder (warm cache, both cores),
and prints each one's ``wall_time_s`` (the study's own, as its result records it) and the
whole command's wall time as the user waits for it, process start included, beside the
``wall_time_s`` of its committed run in ``results/`` (another day). The groups are issue
22's "other" studies (those of ``make studies``, in its order, but the optimal, atlas and
controller ones) and issue 20's atlases (``atlas_upright`` and ``atlas_downward``, the
optimal studies regenerated over the atlas). ``--record`` writes the figures to
``benchmarks/figures/bench_studies.json`` for the README's speed table.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from figures import Figure, report

from baslip import load_problem

ROOT = Path(__file__).resolve().parent.parent
#: Study kinds that issue 22 leaves to the atlas and controller issues.
LONG_KINDS = ("optimal", "atlas", "controllers")
#: The atlases that issue 20 times, and its target for each [s].
ATLASES = ("atlas_upright", "atlas_downward")
ATLAS_TARGET = 60.0
#: The Makefile's lists of studies that ``make studies`` runs, in its order.
MAKE_STUDIES = ("STUDIES", "BRANCHES", "AFTER_CURVES", "VPP_STUDIES")
#: Issue 22's target for the other studies together [s].
OTHER_TARGET = 120.0


def make_studies() -> list[str]:
    """The studies that ``make studies`` runs, in its order (a study may read another's
    results from a sibling folder, as ``convergence_regions`` reads ``grid_downward``'s)."""
    text = (ROOT / "Makefile").read_text().replace("\\\n", " ")
    variables = {name.strip(): value for name, value in
                 (line.split("=", 1) for line in text.splitlines() if re.match(r"^[A-Z_]+ *\??=", line))}
    return [name for group in MAKE_STUDIES for name in variables[group].split()]


def other_studies() -> list[str]:
    """The studies of ``make studies`` whose kind is not in :data:`LONG_KINDS`, in order."""
    return [name for name in make_studies()
            if getattr(load_problem(ROOT / "problems" / f"{name}.yaml").study, "kind", None) not in LONG_KINDS]


def committed_time(name: str) -> float | None:
    """The ``wall_time_s`` of the committed run of ``name`` [s], if there is one."""
    path = ROOT / "results" / name / "result.json"
    if not path.exists():
        return None
    return json.loads(path.read_text()).get("wall_time_s")


@dataclass(frozen=True)
class Timing:
    """One study's run: its own ``wall_time_s`` (from reading the problem to writing the
    last file), and the whole command's wall time [s], process start and exit included."""

    study: float
    command: float


def run(name: str, out: Path) -> Timing:
    """The :class:`Timing` of ``python -m baslip.solve problems/NAME.yaml --out OUT/NAME``."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "baslip.solve", str(ROOT / "problems" / f"{name}.yaml"),
                           "--out", str(out / name), "--quiet"], cwd=ROOT, capture_output=True, text=True)
    command = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{name}: exit {done.returncode}: {done.stderr.strip()}")
    return Timing(json.loads((out / name / "result.json").read_text())["wall_time_s"], command)


def timed(names: list[str]) -> dict[str, Timing]:
    """Each study's :class:`Timing`, run one after the other, with a line of progress each."""
    timings: dict[str, Timing] = {}
    with tempfile.TemporaryDirectory() as out:
        for name in names:
            timings[name] = run(name, Path(out))
            before = committed_time(name)
            committed = "-" if before is None else f"{before:.1f} s"
            print(f"{name:32} {timings[name].study:7.1f} s, the command {timings[name].command:7.1f} s "
                  f"(committed run: {committed})", flush=True)
    return timings


def other_figure(timings: dict[str, Timing]) -> Figure:
    committed = [committed_time(n) for n in timings]
    longest = sorted(timings, key=lambda n: timings[n].study, reverse=True)[:3]
    before = (f"; their committed runs: {sum(c for c in committed if c):.0f} s" if all(committed) else "")
    return Figure(22, f"the {len(timings)} studies of `make studies` other than the optimal, atlas and "
                      "controller ones, one after the other", sum(t.study for t in timings.values()), "s",
                  OTHER_TARGET, "lower",
                  "their `wall_time_s` summed, as the issue measured its 250 s, warm cache (the commands' "
                  f"wall time with process start and exit: {sum(t.command for t in timings.values()):.0f} s); "
                  "longest " + ", ".join(f"`{n}` {timings[n].study:.1f} s" for n in longest) + before)


def atlas_figure(name: str, timing: Timing) -> Figure:
    study = load_problem(ROOT / "problems" / f"{name}.yaml").study
    cells = math.prod(len(axis.values) for axis in study.axes)
    before = committed_time(name)
    committed = "" if before is None else f"; its committed run {before:.0f} s"
    return Figure(20, f"`{name}`: the optimal study over the atlas ({cells} cells, at most "
                      f"{study.max_charts:,} charts each, polished)", timing.study, "s", ATLAS_TARGET, "lower",
                  f"its `wall_time_s`, warm cache (the command: {timing.command:.0f} s){committed}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--group", choices=("other", "atlas", "all"), default="all")
    parser.add_argument("--record", action="store_true", help="write the figures to benchmarks/figures/")
    args = parser.parse_args()
    figures = []
    if args.group in ("other", "all"):
        figures.append(other_figure(timed(other_studies())))
    if args.group in ("atlas", "all"):
        figures += [atlas_figure(name, timing) for name, timing in timed(list(ATLASES)).items()]
    report("bench_studies", figures, args.record and args.group == "all")
    if args.record and args.group != "all":
        print("not recorded: --record needs --group all, so that the record holds every figure", file=sys.stderr)


if __name__ == "__main__":
    main()
