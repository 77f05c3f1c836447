"""``baslip report`` (also ``python -m baslip.report``): write ``results/REPORT.md``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from baslip.files.atomic import write_files_atomically
from baslip.report.page import build_report


def main(argv: list[str] | None = None, prog: str = "python -m baslip.report") -> int:
    """Write ``REPORT.md`` into the results folder given by ``--results``; return the exit status."""
    parser = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path("results"), metavar="DIR")
    args = parser.parse_args(argv)
    text = build_report(args.results)
    write_files_atomically({args.results / "REPORT.md": text})
    print(f"wrote {args.results / 'REPORT.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
