"""Benchmark figures as data, so that the README's speed table is rendered from what the
benchmarks measured, not typed in.

Each benchmark run with ``--record`` writes ``benchmarks/figures/<benchmark>.json``: the
date, the machine (CPU, cores, memory, Python, CasADi, gcc) and a list of figures, each the
measured value beside the target its issue sets. ``speed_table.py`` renders them all.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from dataclasses import asdict, dataclass
from datetime import date
from pathlib import Path

from baslip.files.atomic import json_text, write_files_atomically
from baslip.files.provenance import versions

#: Where ``--record`` writes, one JSON file per benchmark.
FIGURES = Path(__file__).resolve().parent / "figures"
#: The ways a figure can compare with its target.
BETTER = ("lower", "higher")


@dataclass(frozen=True)
class Figure:
    """One measured figure beside its target.

    Parameters
    ----------
    issue : int
        The issue that sets the target.
    what : str
        What was measured, in words (the stride, the tolerance, the study ...).
    value : float
        The measurement, in ``unit``.
    unit : str
        ``us``, ``ms``, ``s``, ``x`` (a ratio of two times in one process), ``/s`` (a rate)
        or ``""``.
    target : float
        The issue's target, in ``unit``.
    better : str
        ``lower`` (the target is an upper bound) or ``higher`` (a lower bound).
    detail : str
        How it was measured: the baseline run in the same process and the ratio to it,
        or the parts of a ratio.
    """

    issue: int
    what: str
    value: float
    unit: str
    target: float
    better: str = "lower"
    detail: str = ""

    def __post_init__(self) -> None:
        if self.better not in BETTER:
            raise ValueError(f"better: expected one of {', '.join(BETTER)}, got {self.better!r}")

    @property
    def met(self) -> bool:
        """Whether the measurement is within the target."""
        return self.value <= self.target if self.better == "lower" else self.value >= self.target


def quantity(value: float, unit: str) -> str:
    """``value`` in ``unit`` as the tables print it: three significant digits, whole numbers
    from 100 up, with thousands separators."""
    number = f"{value:,.0f}" if abs(value) >= 100 else f"{value:.3g}"
    if unit == "x":
        return f"{number}x"
    return f"{number} {unit}" if unit else number


#: The header of a table of figures (:func:`row`).
HEADER = "| issue | figure | measured | target | met | how it was measured |\n|---|---|---|---|---|---|"


def row(figure: Figure) -> str:
    """``figure`` as a row of a markdown table under :data:`HEADER`."""
    bound = "<=" if figure.better == "lower" else ">="
    return (f"| {figure.issue} | {figure.what} | {quantity(figure.value, figure.unit)} | "
            f"{bound} {quantity(figure.target, figure.unit)} | {'yes' if figure.met else '**no**'} | {figure.detail} |")


def report(benchmark: str, figures: list[Figure], save: bool) -> None:
    """Print ``figures`` as a table, and :func:`record` them if ``save``."""
    print("\n".join(["", HEADER, *map(row, figures)]), flush=True)
    if save:
        record(benchmark, figures)


def _first_line(command: list[str]) -> str:
    """The first line that ``command`` prints, or "none" where it cannot run or fails."""
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return "none"
    return (done.stdout or done.stderr).strip().splitlines()[0] if done.returncode == 0 else "none"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gb() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return round(int(line.split()[1]) / 1024**2, 1)
    except OSError:
        pass
    return None


def machine() -> dict[str, object]:
    """The machine a benchmark ran on: CPU model, logical cores, memory [GB], operating
    system (its name only), gcc's version, and the software versions that results record
    (:func:`baslip.files.provenance.versions`)."""
    return {"cpu": _cpu_model(), "cores": os.cpu_count(), "memory_gb": _memory_gb(), "system": platform.system(),
            "gcc": _first_line(["gcc", "-dumpfullversion"]), **versions()}


def record(benchmark: str, figures: list[Figure], folder: Path = FIGURES) -> Path:
    """Write ``folder/<benchmark>.json`` (replacing it whole, never half-written): today's
    date, :func:`machine` and ``figures``. Returns the path."""
    path = folder / f"{benchmark}.json"
    write_files_atomically({path: json_text({"benchmark": benchmark, "date": date.today().isoformat(),
                                             "machine": machine(), "figures": [asdict(f) for f in figures]})})
    print(f"recorded {len(figures)} figures in {path}", file=sys.stderr)
    return path


@dataclass(frozen=True)
class Recorded:
    """One benchmark's recorded run."""

    benchmark: str
    date: str
    machine: dict
    figures: tuple[Figure, ...]


def load(folder: Path = FIGURES) -> list[Recorded]:
    """Every benchmark's recorded run in ``folder``, by benchmark name."""
    runs = []
    for path in sorted(folder.glob("*.json")):
        data = json.loads(path.read_text())
        runs.append(Recorded(data["benchmark"], data["date"], data["machine"],
                             tuple(Figure(**f) for f in data["figures"])))
    return runs
