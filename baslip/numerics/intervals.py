"""Confidence intervals of a measured share (a basin's: starts that returned of all)."""

from __future__ import annotations

import math


def wilson_interval(converged: int, samples: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval of a share ``converged / samples`` (95 % for z = 1.96).
    Its upper end is one minus the lower end of the share that did not converge (the
    interval is symmetric so), so that all of the starts give exactly 1, not 1 - 1e-16."""
    if samples == 0:
        return (0.0, 1.0)
    return (_wilson_lower(converged, samples, z), 1.0 - _wilson_lower(samples - converged, samples, z))


def _wilson_lower(count: int, samples: int, z: float) -> float:
    """The lower end of the Wilson score interval of ``count / samples`` (0 for none)."""
    if count == 0:
        return 0.0
    share, z2 = count / samples, z * z
    centre = (share + z2 / (2 * samples)) / (1 + z2 / samples)
    half = z * math.sqrt(share * (1 - share) / samples + z2 / (4 * samples * samples)) / (1 + z2 / samples)
    return max(0.0, centre - half)
