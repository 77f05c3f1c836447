"""Benchmark of a pass's own error estimate: DOP853's (the engine's) against Verner's 9(8) pair.

    python benchmarks/bench_error_estimates.py [--charts N]

Issue 22 asks whether an embedded pair whose estimate is of the propagated order, such as
Verner's "most efficient" 9(8) pair, would let one pass vouch for a stride (DOP853's own
estimate overstates its error so much that the engine mostly takes a second pass, for the
Richardson test). This measures it on the stance flow, without events: from the touchdown
states of ``--charts`` charts of each committed upright and hanging atlas, over 0.9 of
each one's stance, with N equal steps (within the engine's stability limit h * lambda <=
2). Each pass's estimate is summed over its steps, as the engine sums DOP853's (Hairer's
combined norm of the order-5 and order-3 differences; for Verner's pair the RMS norm of
the order-9 and order-8 difference), relative to max(1, |x|); its true error is the
largest relative difference from a pass of 2,048 DOP853 steps. Prints, per N, the true
errors and the estimates' ratio to them; then, per tolerance, the stage evaluations (N
times 12 or 16 stages) that the least N certified by its own estimate takes, beside the
least N whose true error is within the tolerance.

Verner's coefficients: J. H. Verner, "Numerically optimal Runge-Kutta pairs with interpolants",
Numer. Algor. 53 (2010) 383-396, the pair RKV98.IIa "most efficient" as published on his
page; the script checks their row sums and observed orders before it measures.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import casadi as ca
import numpy as np

from baslip import Params, ReturnMap, Tolerances
from baslip.engine import dop853 as flow
from baslip.engine import kernels
from baslip.engine.outcome import touchdown_guess
from baslip.engine.physics import Physics
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import PD

ROOT = Path(__file__).resolve().parent.parent
#: Step counts a phase compared, and the reference pass's.
COUNTS = (8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256)
REFERENCE_STEPS = 2048
#: Verner's 9(8) pair: the nodes c_i, the stage coefficients a_ij (i, j from 1), and the
#: weights of the order-9 solution and of the embedded order-8 one (zero where absent).
VERNER_NODES = (0.0, .3462e-1, .9702435063878044594828361677100617517633e-1, .1455365259581706689224254251565092627645,
                .561, .2290079115904850126662751771814700052182, .5449920884095149873337248228185299947818, .645,
                .48375, .6757e-1, .25, .6590650618730998549405331618649220295334, .8206, .9012, 1.0, 1.0)
VERNER_STAGES = {
    2: {1: .3462e-1},
    3: {1: -.389335438857287327017042687229284478532e-1, 2: .1359578945245091786499878854939346230295},
    4: {1: .3638413148954266723060635628912731569111e-1, 3: .1091523944686280016918190688673819470733},
    5: {1: 2.025763914393969636805657604282571047511, 3: -7.638023836496292020387602153091964592952,
        4: 6.173259922102322383581944548809393545442},
    6: {1: .5112275589406060872792270881648288397197e-1, 4: .1770823794555021537929910813839068684087,
        5: .80277624092225014536138698108025283759e-3},
    7: {1: .1316006357975216279279871693164256985334, 4: -.2957276252669636417685183174672273730699,
        5: .878137803564295237421124704053886667082e-1, 6: .6213052975225274774321435005639430026100},
    8: {1: .7166666666666666666666666666666666666667e-1, 6: .3305533578915319409260346730051472207728,
        7: .2427799754418013924072986603281861125606},
    9: {1: .71806640625e-1, 6: .3294380283228177160744825466257672816401, 7: .1165190029271822839255174533742327183599,
        8: -.34013671875e-1},
    10: {1: .4836757646340646986611287718844085773549e-1, 6: .3928989925676163974333190042057047002852e-1,
         7: .1054740945890344608263649267140088017604, 8: -.2143865284648312665982642293830533996214e-1,
         9: -.1041229174627194437759832813847147895623},
    11: {1: -.2664561487201478635337289243849737340534e-1, 6: .3333333333333333333333333333333333333333e-1,
         7: -.1631072244872467239162704487554706387141, 8: .3396081684127761199487954930015522928244e-1,
         9: .1572319413814626097110769806810024118077, 10: .2152267478031879552303534778794770376960},
    12: {1: .3689009248708622334786359863227633989718e-1, 6: -.1465181576725542928653609891758501156785,
         7: .2242577768172024345345469822625833796001, 8: .2294405717066072637090897902753790803034e-1,
         9: -.35850052905728761357394424889330334334e-2, 10: .8669223316444385506869203619044453906053e-1,
         11: .4383840651968337846196219974168630120572},
    13: {1: -.4866012215113340846662212357570395295088, 6: -6.304602650282852990657772792012007122988,
         7: -.281245618289472564778284183790118418111, 8: -2.679019236219849057687906597489223155566,
         9: .518815663924157511565311164615012522024, 10: 1.365353187603341710683633635235238678626,
         11: 5.885091088503946585721274891680604830712, 12: 2.802808786272062889819965117517532194812},
    14: {1: .4185367457753471441471025246471931649633, 6: 6.724547581906459363100870806514855026676,
         7: -.425444280164611790606983409697113064616, 8: 3.343279153001265577811816947557982637749,
         9: .617081663117537759528421117507709784737, 10: -.929966123939932833937749523988800852013,
         11: -6.099948804751010722472962837945508844846, 12: -3.002206187889399044804158084895173690015,
         13: .2553202529443445472336424602988558373637},
    15: {1: -.779374086122884664644623040843840506343, 6: -13.93734253810777678786523664804936051203,
         7: 1.252048853379357320949735183924200895136, 8: -14.69150040801686878191527989293072091588,
         9: -.494705058533141685655191992136962873577, 10: 2.242974909146236657906984549543692874755,
         11: 13.36789380382864375813864978592679139881, 12: 14.39665048665068644512236935340272139005,
         13: -.7975813331776800379127866056663258667437, 14: .4409353709534277758753793068298041158235},
    16: {1: 2.058051337466886442151242368989994043993, 6: 22.35793772796803295519317565842520212899,
         7: .90949810997556332745009198137971890783, 8: 35.89110098240264104710550686568482456493,
         9: -3.442515027624453437985000403608480262211, 10: -4.865481358036368826566013387928704014496,
         11: -18.90980381354342625688427480879773032857, 12: -34.26354448030451782929251177395134170515,
         13: 1.264756521695642578827783499806516664686},
}
VERNER_ORDER_9 = {1: .1461197685842315252051541915018784713459e-1, 8: -.3915211862331339089410228267288242030810,
                  9: .2310932500289506415909675644868993669908, 10: .1274766769992852382560589467488989175618,
                  11: .2246434176204157731566981937082069688984, 12: .5684352689748512932705226972873692126743,
                  13: .5825871557215827200814768021863420902155e-1, 14: .1364317403482215641609022744494239843327,
                  15: .3057013983082797397721005067920369646664e-1}
VERNER_ORDER_8 = {1: .1996996514886773085518508418098868756464e-1, 8: 2.191499304949330054530747099310837524864,
                  9: .8857071848208438030833722031786358862953e-1, 10: .1140560234865965622484956605091432032674,
                  11: .2533163805345107065564577734569651977347, 12: -2.056564386240941011158999594595981300493,
                  13: .3408096799013119935160094894224543812830, 16: .4834231373823958314376726739772871714902e-1}


def verner_step(rhs: ca.Function) -> ca.Function:
    """One step of Verner's pair for ``xdot = rhs(x, theta)``: (x, h, theta) -> the order-9
    state and the RMS norm of the order-9 and order-8 difference relative to max(1, |x|)."""
    x, h = ca.SX.sym("x", rhs.size1_in(0)), ca.SX.sym("h")
    theta = ca.SX.sym("theta", rhs.size1_in(1))
    slopes: list = []
    for i in range(1, len(VERNER_NODES) + 1):
        stage = x + h * sum((w * slopes[j - 1] for j, w in VERNER_STAGES.get(i, {}).items()), ca.SX.zeros(x.shape))
        slopes.append(rhs(stage, theta))
    x_next = x + h * sum((w * slopes[i - 1] for i, w in VERNER_ORDER_9.items()), ca.SX.zeros(x.shape))
    difference = h * sum(((VERNER_ORDER_9.get(i, 0.0) - VERNER_ORDER_8.get(i, 0.0)) * slopes[i - 1]
                          for i in range(1, len(VERNER_NODES) + 1)), ca.SX.zeros(x.shape))
    scale = ca.fmax(1, ca.fmax(ca.fabs(x), ca.fabs(x_next)))
    error = ca.sqrt(ca.sumsqr(difference / scale) / x.numel())
    return ca.Function("verner98_step", [x, h, theta], [x_next, error], ["x", "h", "theta"], ["x_next", "error"])


def check_verner() -> None:
    """Stop unless the pair's rows sum to its nodes, its weights to 1, and its two solutions
    show orders near 9 and 8 on a nonlinear scalar test equation."""
    rows = [sum(VERNER_STAGES.get(i, {}).values()) for i in range(1, len(VERNER_NODES) + 1)]
    if max(abs(r - c) for r, c in zip(rows, VERNER_NODES)) > 1e-14:
        raise SystemExit("Verner's coefficients: a row does not sum to its node")
    if abs(sum(VERNER_ORDER_9.values()) - 1) > 1e-14 or abs(sum(VERNER_ORDER_8.values()) - 1) > 1e-14:
        raise SystemExit("Verner's coefficients: the weights do not sum to 1")
    y, t = ca.SX.sym("y"), ca.SX.sym("t")  # t as a state, so that the equation is autonomous
    state = ca.vertcat(y, t)
    rhs = ca.Function("test", [state, ca.SX.sym("none", 1)], [ca.vertcat(-y * y + ca.cos(t) * y + ca.sin(3 * t), 1)])
    step = verner_step(rhs)

    def solve(n: int) -> float:
        x = np.array([0.7, 0.0])
        for _ in range(n):
            x = np.array(step(x, 2.0 / n, 0)[0]).ravel()
        return float(x[0])

    reference = solve(512)
    errors = [abs(solve(n) - reference) for n in (4, 8)]
    observed = np.log2(errors[0] / errors[1])
    if not 8.0 < observed < 10.5:
        raise SystemExit(f"Verner's coefficients: observed order {observed:.2f}, not about 9")


def touchdown_points(charts: int) -> list[tuple[np.ndarray, float, np.ndarray, float]]:
    """(touchdown state, 0.9 of the stance duration [s], theta = (u, p), stiffness rate [1/s])
    at ``charts`` charts of each committed upright and hanging atlas."""
    p = Params()
    pv = p.vector()
    touchdown = kernels.touchdown_state(Physics.of(PD))
    rmap = ReturnMap(Tolerances(1e-12, 1e-12))
    points = []
    for name in ("atlas_upright", "atlas_downward"):
        with open(ROOT / "results" / name / "atlas.csv", newline="") as handle:
            rows = list(csv.DictReader(handle))
        for row in rows[:: max(1, len(rows) // charts)][:charts]:
            X = np.array([float(row[n]) for n in APEX.names])
            u = np.array([float(row[n]) for n in PD.controls.names])
            stride = rmap.stride(X, u, p)
            if not stride.ok:
                continue
            x0 = np.array(touchdown(X, u, pv, touchdown_guess(X, u, pv))[0]).ravel()
            duration = 0.9 * (stride.durations["compression"] + stride.durations["decompression"])
            points.append((x0, duration, np.concatenate([u, pv]), float(kernels.stiffness_rate(X, u, pv, PD))))
    return points


class Passes:
    """Passes of N equal steps of a one-step method, each chain built once."""

    def __init__(self, step: ca.Function, stages: int):
        self.step, self.stages, self._chains = step, stages, {}

    def __call__(self, n: int, x0, duration: float, theta) -> tuple[np.ndarray, float]:
        """(the state after ``duration`` [s] in ``n`` steps, the steps' summed estimate)."""
        if n not in self._chains:
            self._chains[n] = flow.chain(self.step, n)
        nodes, errors = self._chains[n](x0, duration / n, theta)
        return np.array(nodes[:, -1]).ravel(), float(np.sum(np.array(errors)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--charts", type=int, default=40, help="charts of each atlas (default 40)")
    args = parser.parse_args()
    check_verner()
    rhs = kernels.stance_rhs(Physics.of(PD))
    dop = flow.step_function(rhs)
    inputs = dop.mx_in()  # the engine's step without its watched minima
    methods = {"DOP853": Passes(ca.Function("dop853_value", inputs, dop.call(inputs)[:2]), 12),
               "Verner 9(8)": Passes(verner_step(rhs), 16)}
    points = touchdown_points(args.charts)
    reference = methods["DOP853"]
    print(f"{len(points)} touchdown states; true error against {REFERENCE_STEPS:,} DOP853 steps")
    # measured[method][k][n]: (estimate, true error) of point k's pass of n steps, for the
    # counts within the stability limit
    measured: dict[str, list[dict[int, tuple[float, float]]]] = {m: [] for m in methods}
    for x0, duration, theta, rate in points:
        exact = reference(REFERENCE_STEPS, x0, duration, theta)[0]
        scale = np.maximum(1.0, np.abs(exact))
        for name, passes in methods.items():
            runs = {}
            for n in (n for n in COUNTS if duration * rate / n <= 2.0):
                state, estimate = passes(n, x0, duration, theta)
                runs[n] = (estimate, float(np.max(np.abs(state - exact) / scale)))
            measured[name].append(runs)
    print("N | " + " | ".join(f"{m}: true error, estimate / true (median, 10th percentile, least)" for m in methods))
    for n in COUNTS[:7]:
        print(f"{n} | " + " | ".join(_ratios([runs[n] for runs in measured[m] if n in runs]) for m in methods))
    for tolerance in (1e-10, 1e-12):
        print(f"tol {tolerance:g}, the least pass that its own estimate certifies, median over the states: "
              + "; ".join(_certified(name, measured[name], passes.stages, tolerance) for name, passes in methods.items()))


def _ratios(pairs: list[tuple[float, float]]) -> str:
    """The median true error, and the estimates' ratio to it, of (estimate, true error)
    pairs above round-off."""
    pairs = [(e, t) for e, t in pairs if t > 1e-14]
    if not pairs:
        return "-"
    ratio = np.array([e / t for e, t in pairs])
    return (f"{np.median([t for _, t in pairs]):.1e}, {np.median(ratio):.1f} "
            f"({np.percentile(ratio, 10):.2f}, {ratio.min():.2f})")


def _certified(name: str, measured: list[dict[int, tuple[float, float]]], stages: int, tolerance: float) -> str:
    """The stage evaluations of the least pass whose own estimate is within ``tolerance``,
    beside those of the least pass whose true error is, and how often the first is the
    smaller (a pass certified with its true error above the tolerance)."""
    by_estimate, by_truth, unsafe = [], [], 0
    for runs in measured:
        first_estimate = next((n for n, (e, _) in runs.items() if e <= tolerance), None)
        first_truth = next((n for n, (_, t) in runs.items() if t <= tolerance), None)
        if first_estimate is not None and first_truth is not None:
            by_estimate.append(first_estimate * stages)
            by_truth.append(first_truth * stages)
            unsafe += first_estimate < first_truth
    return (f"{name} {np.median(by_estimate):.0f} stage evaluations (true error alone: {np.median(by_truth):.0f}; "
            f"certified below the truth: {unsafe} of {len(by_estimate)})")


if __name__ == "__main__":
    main()
