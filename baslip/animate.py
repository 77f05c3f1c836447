"""``python -m baslip.animate``: kept as an entry point; the command is :mod:`baslip.cli.animate`."""

import sys

from baslip.cli.animate import main

if __name__ == "__main__":
    sys.exit(main())
