"""Checks of the arguments of the return map's public functions, before any compiled code runs.

A bad argument (a wrong shape, a type that is not a number, a count out of range, or a
size that would exhaust memory or run without end) raises :class:`ArgumentError`, an
:class:`~baslip.errors.InputError` naming the argument, in one line. Values that are
numbers but not finite pass: a stride from them is the named fall ``non-finite state``.

The size limits are chosen from memory and time: a few hundred MB and minutes at most.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from baslip.errors import ArgumentError
from baslip.model.dynamics import PARAMS
from baslip.model.ranges import parameter_fault

#: The most strides one call runs from one apex (``simulate``, ``jacobians``, a
#: trajectory): at a few ms a stride, minutes.
MAX_STRIDES = 100_000
#: The most apexes one call holds (the rows of ``strides``; rows x (strides + 1) of
#: ``simulate_many``): about 300 MB as Python objects.
MAX_APEXES = 2_000_000
#: The most samples one trajectory or motion holds in all (strides x samples in its
#: phases): a motion's row takes about 2 kB while it is built, so about 2 GB at most.
MAX_SAMPLES = 1_000_000
#: Longest text of a value quoted in a message.
_SHOWN = 40


def shown(value: object) -> str:
    """``repr(value)`` cut to a readable length (a 5000-digit number is not printed)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**_SHOWN:
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"  # str() refuses 4300+
    text = repr(value) if not isinstance(value, np.ndarray) else f"an array of shape {value.shape}"
    return text if len(text) <= _SHOWN else text[: _SHOWN - 3] + "..."


def whole_number(value: object, name: str, least: int, most: int) -> int:
    """``value`` as an int if it is a whole number (not a bool) in [least, most].

    Parameters
    ----------
    value : object
        The argument.
    name : str
        Its name, for the message.
    least, most : int
        The range allowed, both included.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ArgumentError(name, f"expected a whole number from {least} to {most}, got {shown(value)}")
    if not least <= int(value) <= most:
        raise ArgumentError(name, f"must be from {least} to {most}, got {shown(value)}")
    return int(value)


def positive_number(value: object, name: str, unit: str) -> float:
    """``value`` as a float if it is a finite positive number (not a bool); ``unit`` is its unit."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise ArgumentError(name, f"expected a finite number of {unit}, got {shown(value)}")
    if float(value) <= 0.0:
        raise ArgumentError(name, f"must be positive, got {float(value):g} {unit}")
    return float(value)


def _numbers(value: object, name: str) -> np.ndarray:
    """``value`` as a float array, or an error naming ``name``: text, objects or ragged
    sequences are not numbers."""
    if isinstance(value, (str, bytes)) or value is None:
        raise ArgumentError(name, f"expected numbers, got {type(value).__name__}")
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentError(name, f"expected numbers, got {shown(value)}") from None
    return array


def vector(value: object, name: str, size: int) -> np.ndarray:
    """``value`` as a flat float array of ``size`` entries (any shape holding that many,
    as a column); otherwise an error naming ``name``."""
    array = _numbers(value, name)
    if array.size != size or (array.ndim > 1 and max(array.shape) != size):
        raise ArgumentError(name, f"expected {size} numbers, got shape {array.shape}")
    return array.ravel()


def rows(value: object, name: str, size: int, most: int = MAX_APEXES) -> np.ndarray:
    """``value`` as an (n, size) float array (one row of ``size`` entries counts as n = 1),
    n at most ``most``; otherwise an error naming ``name``."""
    array = _numbers(value, name)
    if array.ndim == 1:
        array = array[None, :] if array.size else array.reshape(0, size)
    if array.ndim != 2 or array.shape[1] != size:
        raise ArgumentError(name, f"expected rows of {size} numbers, got shape {array.shape}")
    if len(array) > most:
        raise ArgumentError(name, f"{len(array)} rows exceed the limit of {most}")
    return array


def columns(value: object, name: str, size: int) -> np.ndarray:
    """``value`` as a (size, K) float array (``size`` entries count as K = 1), K at most
    :data:`MAX_APEXES`; otherwise an error naming ``name``."""
    array = _numbers(value, name)
    if array.ndim == 1 and array.size == size:
        array = array[:, None]
    if array.ndim != 2 or array.shape[0] != size:
        raise ArgumentError(name, f"expected shape ({size}, K), got shape {array.shape}")
    if array.shape[1] > MAX_APEXES:
        raise ArgumentError(name, f"{array.shape[1]} columns exceed the limit of {MAX_APEXES}")
    return array


def row_controls(value: object, name: str, count: int, size: int) -> np.ndarray:
    """``value`` as (count, size) controls: one control vector for every row, or one row each."""
    array = _numbers(value, name)
    if array.shape not in ((size,), (1, size), (count, size)):
        raise ArgumentError(name, f"expected {size} numbers or {count} rows of them, got shape {array.shape}")
    return np.broadcast_to(array.reshape(-1, size), (count, size))


def parameters(value: object, name: str = "params") -> np.ndarray:
    """The parameter vector (m, I, k, rho0, d, g) of a :class:`~baslip.model.dynamics.Params`
    (checked when it was built) or of a sequence of 6 numbers, each finite one in its
    physical range (:data:`~baslip.model.ranges.PARAM_RANGES`)."""
    if hasattr(value, "vector"):
        return value.vector()
    p = vector(value, name, PARAMS.size)
    for entry, number in zip(PARAMS.names, p):
        fault = parameter_fault(entry, float(number)) if math.isfinite(number) else None
        if fault is not None:
            raise ArgumentError(f"{name}.{entry}", fault)
    return p
