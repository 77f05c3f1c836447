"""``python -m baslip.solve``: kept as an entry point; the command is :mod:`baslip.cli.solve`."""

import sys

from baslip.cli.solve import main

if __name__ == "__main__":
    sys.exit(main())
