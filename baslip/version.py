"""The version of baslip: the one place it is written. The wheel's metadata takes it from
here (``[tool.hatch.version]`` in ``pyproject.toml``), so that reading it at run time costs
no look-up of installed distributions (``importlib.metadata`` took 22 ms of a warm gait's
run)."""

__version__ = "0.2.0"
