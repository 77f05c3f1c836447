"""The command line: thin layers over the Python verbs (``baslip``, ``python -m
baslip.solve``, ...)."""


def main(argv: list[str] | None = None) -> int:
    """The ``baslip`` command; kept here too, so that a console script installed before
    the command moved to :mod:`baslip.cli.main` still runs."""
    from baslip.cli.main import main as command

    return command(argv)
