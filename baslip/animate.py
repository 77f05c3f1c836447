"""``python -m baslip.animate``: kept as an entry point; the command is :mod:`baslip.cli.animate`."""

import sys

if __name__ == "__main__":  # not when a process spawned by multiprocessing (a Dask LocalCluster's) imports it as __mp_main__
    from baslip.cli.animate import main

    sys.exit(main())
