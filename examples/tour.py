"""A tour of baslip from Python: solve, inspect, plot, simulate, a trajectory, a small
sweep and a branch, all through the Python verbs (no YAML text, no command line). Run
it from the repository root (about half a minute):

    .venv/bin/python examples/tour.py [OUTPUT_FOLDER]

Everything it writes goes into OUTPUT_FOLDER (default: runs/tour), never into results/.
In a notebook, paste the steps into cells: results show themselves as tables there.
(The ``if __name__ == "__main__":`` guard below is not needed for baslip's worker
processes, which never import the script that starts them.)
"""

import sys
from pathlib import Path

import numpy as np

import baslip
from baslip import ReturnMap, Tolerances, load_problem, solve_problem


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("runs/tour")
    out.mkdir(parents=True, exist_ok=True)
    problems = baslip.problems_dir()

    # 1. Solve the hanging-trunk gait and look at it.
    result = solve_problem(load_problem(problems / "downward.yaml"))
    print(repr(result))
    print(result.summary())

    # 2. Its figure (returned, not written: save it where you like).
    result.plot().savefig(out / "downward_gait.png", dpi=110)

    # 3. Simulate ten strides from a perturbed apex: the stable gait pulls it back.
    rmap = ReturnMap(Tolerances(1e-10, 1e-10))
    start = result.X + np.array([0.005, 0.0, 0.02, 0.0])  # 5 mm higher, 2 cm/s faster
    run = rmap.simulate(start, result.u, result.params, strides=10)
    eps = np.linalg.norm(run.apexes - result.X, axis=1) / np.linalg.norm(result.X)
    print("relative distance from the gait (eq. 4.1), stride by stride:", np.round(eps, 4))

    # 4. The continuous motion: the hip motor's work equals the change of energy.
    motion = result.trajectory(strides=1, samples=200)
    print(motion, f"work of the hip torque {motion.work_of_torque():.2e} J,",
          f"energy change {motion['energy'][-1] - motion['energy'][0]:.2e} J")
    (out / "downward_trajectory.csv").write_text(motion.csv_text())

    # 5. A small sweep over speed: the shipped problem, changed and checked in Python.
    speeds = load_problem(problems / "speed_sweep.yaml").replace(
        name="tour_sweep", study={"kind": "sweep", "vary": {"ydot": [0.3, 0.7, 0.1]}})
    sweep_results = baslip.run(speeds, out=out / "tour_sweep", progress=False)
    print(sweep_results)
    print(sweep_results.summary())

    # 6. A branch: the SLIP's stable band in touchdown angle, with its two edges. Without
    #    ``out`` nothing is written; the result holds its tables.
    slip = load_problem(problems / "continuation_slip_attack.yaml")
    band = baslip.run(slip.replace(continuation={"parameter": "theta_td", "range": ["20 deg", "25 deg"],
                                                 "step": 0.05, "direction": 1, "plot": "z"}), progress=False)
    print(band)
    for point in band.record["special_points"]:
        print(f"  {point['type']} at theta_td = {np.degrees(point['theta_td']):.4f} deg")
    band.plot()["diagram"].savefig(out / "band_diagram.png", dpi=110)
    print(f"wrote the tour's files into {out}/")


if __name__ == "__main__":
    main()
