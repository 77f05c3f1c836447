"""Named layouts of flat state, control and parameter vectors.

Symbolic code indexes vectors by name through a :class:`Layout`, never by bare
integers, so that ``STANCE.get(x, "rhodot")`` reads like the physics it encodes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class Layout:
    """An ordered tuple of entry names for a flat vector."""

    names: tuple[str, ...]

    @property
    def size(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Position of entry ``name``; raises KeyError naming the layout's entries."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{name!r} is not one of {self.names}") from None

    def get(self, vec: Any, name: str) -> Any:
        """Entry ``name`` of ``vec`` (CasADi or numpy); a row when ``vec`` has many columns."""
        i = self.index(name)
        shape: tuple[int, ...] = getattr(vec, "shape", ())
        return vec[i, :] if len(shape) == 2 and shape[1] > 1 else vec[i]

    def unpack(self, vec: Any) -> dict[str, Any]:
        """All entries (rows) of ``vec`` keyed by name."""
        return {name: self.get(vec, name) for name in self.names}

    def pack(self, values: Mapping[str, Any]) -> Any:
        """Stack ``values`` in layout order: a CasADi column if any entry is symbolic."""
        missing = [n for n in self.names if n not in values]
        if missing:
            raise KeyError(f"missing entries {missing} for layout {self.names}")
        entries = [values[n] for n in self.names]
        if any(isinstance(e, (ca.SX, ca.MX, ca.DM)) for e in entries):
            return ca.vertcat(*entries)
        return np.array(entries, dtype=float)

    def sym(self, name: str, kind: Any = ca.SX) -> Any:
        """A fresh symbolic column vector of this layout's size."""
        return kind.sym(name, self.size)

    def to_dict(self, vec: ArrayLike) -> dict[str, float]:
        """Plain-float dictionary of a numeric vector, for JSON output."""
        flat = np.asarray(vec, dtype=float).ravel()
        return {name: float(flat[i]) for i, name in enumerate(self.names)}
