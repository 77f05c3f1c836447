"""``python -m baslip``: the ``baslip`` command."""

import sys

from baslip.cli.main import main

sys.exit(main())
