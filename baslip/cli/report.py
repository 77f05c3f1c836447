"""``baslip report`` (also ``python -m baslip.report``): write ``results/REPORT.md``."""

from __future__ import annotations

import sys
from pathlib import Path

from baslip.cli.common import EXIT_BAD_INPUT, OneLineParser, place_refusal
from baslip.diagnostics import show_on_stderr
from baslip.errors import InputError
from baslip.files.atomic import write_files_atomically
from baslip.report.page import build_report

#: What ``--help`` says the command does (plain text: help is no docstring).
DESCRIPTION = "write REPORT.md, the studies' results and figures in one page, into the results folder " \
              "(also python -m baslip.report)"


def main(argv: list[str] | None = None, prog: str = "python -m baslip.report") -> int:
    """Write ``REPORT.md`` into the results folder given by ``--results``; return the exit status."""
    show_on_stderr()  # diagnostics (progress, notes) go through logging; show them
    parser = OneLineParser(prog=prog, description=DESCRIPTION)
    parser.add_argument("--results", type=Path, default=Path("results"), metavar="DIR",
                        help="the results folder whose studies the report gathers; REPORT.md is written there "
                        "(default: results)")
    args = parser.parse_args(argv)
    refusal = place_refusal("--results", args.results, existing=True)
    if refusal is not None:
        print(refusal, file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        text = build_report(args.results)
    except InputError as err:  # a damaged table, named with its line
        print(f"error: --results {args.results}: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (OSError, ValueError, KeyError, TypeError, IndexError) as err:  # the folder's files are not baslip's
        print(f"error: --results {args.results}: cannot read the studies' results there "
              f"({type(err).__name__}: {str(err).splitlines()[0][:120] if str(err) else ''})", file=sys.stderr)
        return EXIT_BAD_INPUT
    write_files_atomically({args.results / "REPORT.md": text})
    print(f"wrote {args.results / 'REPORT.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
