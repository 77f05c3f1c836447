"""``python -m baslip.animate``: kept as an entry point; the command is :mod:`baslip.cli.animate`."""

import sys

if __name__ == "__main__":  # not when a spawned worker imports this module as __mp_main__
    from baslip.cli.animate import main

    sys.exit(main())
