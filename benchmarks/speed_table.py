"""Render the README's speed table from the benchmarks' recorded figures.

    python benchmarks/speed_table.py           # rewrite the table in README.md
    python benchmarks/speed_table.py --check   # exit 1 if README.md's table is not the render

The table sits between the two marker lines :data:`BEGIN` and :data:`END` of the README.
Its figures are those that the benchmarks wrote with ``--record`` into
``benchmarks/figures/`` (see ``figures.py``): each beside its issue's target, with how it
was measured and on which machine.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from figures import FIGURES, HEADER, Recorded, load, row

README = Path(__file__).resolve().parent.parent / "README.md"
BEGIN = "<!-- speed table: rendered by benchmarks/speed_table.py from benchmarks/figures/; do not edit by hand -->"
END = "<!-- end of the speed table -->"


def machine_line(machine: dict) -> str:
    """The machine of a recorded run (:func:`figures.machine`) in words."""
    memory = f", {machine['memory_gb']:g} GB" if machine.get("memory_gb") else ""
    return (f"{machine['cpu']}, {machine['cores']} logical cores{memory}, {machine['system']}; "
            f"Python {machine['python']}, CasADi {machine['casadi']}, numpy {machine['numpy']}, gcc {machine['gcc']}")


def render(runs: list[Recorded]) -> str:
    """The speed table (with its marker lines) of the recorded ``runs``."""
    machines: dict[str, list[str]] = {}
    for run in runs:
        machines.setdefault(machine_line(run.machine), []).append(f"`{run.benchmark}.py` {run.date}")
    lines = [BEGIN, ""]
    for described, benchmarks in machines.items():
        lines.append(f"Measured on {described} ({', '.join(benchmarks)}).")
        lines.append("")
    figures = sorted((f for run in runs for f in run.figures), key=lambda f: f.issue)
    met = sum(f.met for f in figures)
    lines += [f"{met} of {len(figures)} figures meet their targets.", "",
              HEADER, *map(row, figures), "", END]
    return "\n".join(lines)


def replaced(text: str, table: str) -> str:
    """``text`` with the part from :data:`BEGIN` to :data:`END` replaced by ``table``."""
    if text.count(BEGIN) != 1 or text.count(END) != 1 or text.index(BEGIN) > text.index(END):
        raise ValueError("the README needs exactly one pair of the speed table's marker lines, in order")
    return text[:text.index(BEGIN)] + table + text[text.index(END) + len(END):]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the README's table is not the render")
    parser.add_argument("--readme", type=Path, default=README)
    parser.add_argument("--figures", type=Path, default=FIGURES)
    args = parser.parse_args(argv)
    runs = load(args.figures)
    if not runs:
        print(f"error: {args.figures}: no recorded figures (run the benchmarks with --record)", file=sys.stderr)
        return 2
    text = args.readme.read_text()
    try:
        new = replaced(text, render(runs))
    except ValueError as error:
        print(f"error: {args.readme}: {error}", file=sys.stderr)
        return 2
    if args.check:
        if new != text:
            print(f"{args.readme}: the speed table is not the render of {args.figures} "
                  f"(run python benchmarks/speed_table.py)", file=sys.stderr)
            return 1
        return 0
    args.readme.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
