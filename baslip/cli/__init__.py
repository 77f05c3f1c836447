"""The command line: thin layers over the Python verbs (``baslip``, ``python -m
baslip.solve``, ...)."""
