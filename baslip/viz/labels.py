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

#: How the hip laws are named in figure titles.
LAW_NAMES = {"pd": "PD hip torque", "vpp": "virtual pivot point"}


def figure_title(name: str, params, law: str) -> str:
    """The title line of a run's figures: the problem's name, its hip law and the body it
    runs with, so that a figure taken out of its folder says what it shows.

    Parameters
    ----------
    name : str
        The problem's name.
    params : Params
        The model parameters (m [kg], I [kg m^2], k [N/m], rho0 [m], d [m]).
    law : str
        The hip law's name (``pd`` or ``vpp``).

    Returns
    -------
    str
        Two lines, for example ``grid_downward`` and ``PD hip torque; m = 1 kg, I = 0.0033
        kg m^2, k = 1000 N/m, rho0 = 0.2 m, d = 0.04 m``.
    """
    body = (f"m = {params.m:g} kg, I = {params.I:g} kg m^2, k = {params.k:g} N/m, rho0 = {params.rho0:g} m, "
            f"d = {params.d:g} m")
    return f"{name}\n{LAW_NAMES.get(law, law)}; {body}"


def problem_title(problem) -> str:
    """:func:`figure_title` of a :class:`~baslip.problem.reader.Problem`.

    Parameters
    ----------
    problem : Problem
        The problem whose name, parameters and hip law the title gives.

    Returns
    -------
    str
        The title line.
    """
    return figure_title(problem.name, problem.params, problem.hip_law.name)
