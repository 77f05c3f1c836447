"""Gains drawn over their bounds: the independent starts of the searches (the optimal
study's, the atlas's seeds, and the start from the body alone where its paths break)."""

from __future__ import annotations

import numpy as np

from baslip.gait.shooting import FixedPointSpec
from baslip.model.quantities import nominal


def random_start(spec: FixedPointSpec, rng: np.random.Generator) -> dict[str, float]:
    """Gains to hold while solving a starting gait, drawn over their whole range (the
    problem's bounds inside the physical ones): uniform in asinh(value / nominal), the
    nominal scale the body's (:func:`~baslip.model.quantities.nominal`), so that gains of
    0.01 and of 100 times it are both drawn, not only the large ones, alike at every size.

    Only the gains (the law's ``drawn`` controls: Kp and Kd under PD, r_vpp under VPP)
    are drawn: the rest of the start comes from the problem's guess. With everything
    drawn, 1 start in 16 gave a fixed point at the upright (0.5 m/s, 0.4 m) cell; with the
    gains held, 8 in 16 did, with radii from 3.6 to 1500.
    """
    held = {}
    for name in spec.law.drawn:
        if name in spec.fixed:
            continue
        lo, hi = spec.bounds_of(name)
        sigma = nominal(name, spec.params)
        s = rng.uniform(np.arcsinh(lo / sigma), np.arcsinh(hi / sigma))
        held[name] = float(np.clip(sigma * np.sinh(s), lo, hi))
    return held
