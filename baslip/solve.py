"""``python -m baslip.solve``: kept as an entry point; the command is :mod:`baslip.cli.solve`."""

import sys

if __name__ == "__main__":  # not when a process spawned by multiprocessing (a Dask LocalCluster's) imports it as __mp_main__
    from baslip.cli.solve import main

    sys.exit(main())
