"""How special points are named to a reader: in figures, the report and the summaries.

The analysis names them by a short key (``period_doubling``, ``bogdanov_takens``); these
are the words shown for those keys.
"""

#: Special points of a branch (codimension one).
SPECIAL_NAMES = {"fold": "fold", "turning_point": "turning point", "period_doubling": "period doubling",
                 "neimark_sacker": "Neimark-Sacker", "branch_point": "branch point"}

#: Codimension-two points on a bifurcation curve.
CODIM2_NAMES = {
    "cusp": "cusp", "bogdanov_takens": "Bogdanov-Takens (double +1)", "fold_flip": "fold-flip",
    "fold_neimark_sacker": "fold-Neimark-Sacker", "generalised_period_doubling": "generalised period doubling",
    "resonance_1_1": "1:1 resonance", "resonance_1_2": "1:2 resonance", "resonance_1_3": "1:3 resonance",
    "resonance_1_4": "1:4 resonance",
}

#: The stride-to-stride controllers of a ``controllers`` study.
CONTROLLER_NAMES = {
    "constant": "constant control", "feedback": "LQR feedback (all controls)",
    "pivot": "pivot feedback (r_vpp only)", "horizon": "receding-horizon re-solve", "resolve": "one-stride re-solve",
}
