"""``python -m baslip``: the ``baslip`` command."""

import sys

from .cli import main

sys.exit(main())
