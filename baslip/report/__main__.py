"""``python -m baslip.report``: the command is :mod:`baslip.cli.report`."""

import sys

from baslip.cli.report import main

sys.exit(main())
