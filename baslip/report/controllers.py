"""The report's controller comparison: every shipped gait's basins under its stride-to-stride
controllers, box by box, with their intervals and costs, and the best controller of each."""

from __future__ import annotations

import math

from baslip.report.evidence import Evidence, claim

#: The controller comparisons the report reads, and how its table names their gaits.
CONTROLLER_GAITS = {
    "controllers_upright": "upright (shipped, PD)",
    "controllers_upright_best": "upright (most stable of the atlas, PD)",
    "controllers_downward": "hanging (PD)",
    "controllers_vpp": "upright (VPP, thesis scale)",
    "controllers_vpp_human": "upright (VPP, human scale)",
}


def controller_claims(ev: Evidence) -> list[str]:
    """One claim: the basin table of every controller comparison that was run."""
    found = {name: ev.summary(name) for name in CONTROLLER_GAITS}
    runs = {name: summary for name, summary in found.items() if summary is not None and "basins" in summary}
    if not runs:
        return []
    first = next(iter(runs.values()))
    boxes = first["boxes"]
    header = ("| gait | controller | " + " | ".join(f"{b:g}x" for b in boxes)
              + " | largest 90 % box | median cost a stride |\n|---|---|" + "---|" * (len(boxes) + 2))
    rows = [_row(name, summary, controller, basin) for name, summary in runs.items()
            for controller, basin in summary["basins"].items()]
    feedback = "; ".join(f"{CONTROLLER_GAITS[name]}: {_feedback_text(summary)}" for name, summary in runs.items())
    best = "; ".join(f"{CONTROLLER_GAITS[name]}: {_best_text(summary)}" for name, summary in runs.items())
    kept = "; ".join(f"{CONTROLLER_GAITS[name]}, {controller}: {share:.0%}" for name, summary in runs.items()
                     for controller, share in _kept_up(summary))
    kept_text = (f"\n\nKept up without converging or settling within {first['strides']} strides (most of the 1x "
                 f"box; neither returned nor fallen, so not counted above): {kept}." if kept else "")
    box = ", ".join(f"{k} +-{v:g}" for k, v in first["perturbation"].items())
    return [claim(
        "Under event-based feedback and receding-horizon re-solve: yes, with measured basins",
        "time-varying control kept an upright runner hopping; chapter 5 asks for cheaper functional control laws.",
        f"apex states drawn uniformly from boxes b times X* {box} (SI units, rad; the human-scale VPP gait's box is "
        f"its own, see its problem file), run for at most {first['strides']} strides. Each cell is the share that "
        f"returned (converged within {first['tolerance']:g}, eq. 4.1, or, at a VPP gait, settled on a neighbouring "
        "gait of its family) with its Wilson 95 % interval; constant, feedback and pivot from "
        f"{first['basins']['constant']['per_box'][0]['samples']} starts a box, {_re_solve_starts(runs)}.\n\n"
        + header + "\n" + "\n".join(rows) + f"\n\nThe best controller of each gait (the largest 90 % box, then "
        f"the most returned in the largest box, then the least cost): {best}.{kept_text}\n\nThe feedback chosen: "
        f"{feedback}.\n",
        "goes further",
        "The tuned feedback u = u* + K (X - X*) is the cheap functional law chapter 5 asks for: a matrix product a "
        "stride. Where the constant law is unstable it makes the gait asymptotically stable, and its basin is "
        "measured here, not assumed. The pivot feedback is Sharbafi et al.'s (2013) scheme on a VPP gait: the same "
        "LQR choice, moving the pivot alone, the touchdown angle held. The receding-horizon re-solve reaches in two strides the apex direction that "
        "dr/du of rank 3 leaves out in one, at the cost of a few Jacobian strides at every apex; the one-stride "
        "re-solve is greedy. At a VPP gait the symmetry multiplier 1 is out of every controller's reach at first "
        "order, so a run returns to the family of gaits, not to X* itself. The claims are as wide as these boxes.",
        [f"{name}/basins.png" for name in runs],
    )]


def _row(name: str, summary: dict, controller: str, basin: dict) -> str:
    cells = []
    for b in basin["per_box"]:
        share, (lo, hi) = b["returned_fraction"], b["ci95"]
        # One decimal: from 1,000 starts a whole percent would show 89.8 % as the 90 % it misses.
        cells.append("-" if share is None else f"{share:.1%} ({lo:.1%}-{hi:.1%})")
    largest = basin["largest_90_box"]
    median = _median_cost(basin)
    cost = f"{median:.2f} ms" if math.isfinite(median) else "-"
    return (f"| {CONTROLLER_GAITS[name]} | {controller} | " + " | ".join(cells)
            + f" | {'none' if largest is None else f'{largest:g}x'} | {cost} |")


def _feedback_text(summary: dict) -> str:
    """The linear feedbacks chosen for a gait (feedback, and pivot where it ran)."""
    texts = []
    for name in ("feedback", "pivot"):
        if name in summary:
            f = summary[name]
            weights = (f" (weight exponents {', '.join(f'{w:g}' for w in f['weight_exponents'])})"
                       if f["weight_exponents"] else "")
            texts.append(f"{'' if name == 'feedback' else 'pivot: '}{f['kind']}{weights}, closed-loop radius "
                         f"{f['closed_loop_radius']:.3f}")
    return ", ".join(texts) + f", open loop {summary['gait']['spectral_radius']:.3g}"


def best_controller(summary: dict) -> str:
    """The controller of ``summary`` with the largest box where >= 90 % return, then the
    largest returned share in the largest box, then the least median cost a stride."""
    def rank(item):
        name, basin = item
        largest = basin["largest_90_box"] or 0.0
        last = basin["per_box"][-1]["returned_fraction"] or 0.0
        return (largest, last, -_median_cost(basin))

    return max(summary["basins"].items(), key=rank)[0]


def _best_text(summary: dict) -> str:
    name = best_controller(summary)
    basin = summary["basins"][name]
    largest, last = basin["largest_90_box"], basin["per_box"][-1]
    box = "no box with 90 % returned" if largest is None else f"90 % or more returned up to the {largest:g}x box"
    return f"{name} ({box}; {last['returned_fraction']:.1%} in the {last['box']:g}x box)"


def _re_solve_starts(runs: dict) -> str:
    """How many starts a box each re-solving controller ran, over the comparisons ``runs``
    (they run fewer than the batched ones: each apex costs them Jacobian strides); where
    the gaits differ, the count of each gait."""
    parts = []
    for name, text in {"horizon": "the receding horizon", "resolve": "the one-stride re-solve"}.items():
        counts = {gait: summary["basins"][name]["per_box"][0]["samples"] for gait, summary in runs.items()
                  if name in summary["basins"]}
        if len(set(counts.values())) == 1:
            parts.append(f"{text} from {next(iter(counts.values()))}")
        elif counts:
            parts.append(f"{text} from " + ", ".join(f"{n} ({CONTROLLER_GAITS[gait]})" for gait, n in counts.items()))
    return ", ".join(parts) if parts else "no re-solving controller"


def _kept_up(summary: dict) -> list[tuple[str, float]]:
    """(controller, share) where most of the smallest box was kept up without returning:
    a slow convergence (a closed loop of radius near 1) that the stride limit cut short."""
    found = []
    for controller, basin in summary["basins"].items():
        share = basin["per_box"][0]["bounded_fraction"]
        if share is not None and share > 0.5:
            found.append((controller, share))
    return found


def _median_cost(basin: dict) -> float:
    """The median over boxes of the median cost a stride [ms] (inf where none ran)."""
    costs = sorted(b["median_ms_per_stride"] for b in basin["per_box"] if b["median_ms_per_stride"] is not None)
    return costs[len(costs) // 2] if costs else math.inf
