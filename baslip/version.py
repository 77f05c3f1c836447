"""The installed version of baslip ("unknown" in a source tree that is not installed)."""

from importlib import metadata as _metadata

try:
    __version__ = _metadata.version("baslip")
except _metadata.PackageNotFoundError:
    __version__ = "unknown"
