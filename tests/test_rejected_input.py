"""Specification of rejected input: a fuzz suite over every key, study kind and
continuation setting, and the command line.

Every bad input gives exit code 2 and exactly one short line on stderr that starts with
"error:" and names the key (or the file, folder or option) at fault; no traceback, and
nothing is written. The generated cases come in classes, which docs/guides/problem-files.md's "Rejected
input" section lists. Valid but unusual spellings of a problem are accepted, and mean the
same problem as the plain spelling.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from baslip.cli.solve import main
from baslip.files.provenance import problem_hash
from baslip.problem.reader import load_problem

ROOT = Path(__file__).resolve().parents[1]
#: Longest error line accepted.
MAX_LINE = 300


def base(name: str) -> dict:
    return yaml.safe_load((ROOT / "problems" / f"{name}.yaml").read_text())


def put(data: dict, path: str, value) -> dict:
    """A deep copy of ``data`` with the entry at the dotted ``path`` set to ``value``."""
    data = json.loads(json.dumps(data))
    *parents, last = path.split(".")
    node = data
    for key in parents:
        node = node.setdefault(key, {})
    node[last] = value
    return data


def dump(data) -> str:
    return yaml.safe_dump(data, sort_keys=False, width=1000)


#: Values no number in a problem may take.
NOT_A_NUMBER = {"text": "fast", "list": [1, 2], "map": {"a": 1}, "bool": True, "null": None}
NOT_FINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
TOO_LARGE = {"1e300": 1e300, "-1e300": -1e300, "10^400": 10**400}
BAD_NUMBERS = {**NOT_A_NUMBER, **NOT_FINITE, **TOO_LARGE}


def number_cases(problem: str, path: str, values=BAD_NUMBERS, key: str | None = None):
    data = base(problem)
    return [(f"{path}={label}", dump(put(data, path, value)), key or path) for label, value in values.items()]


CASES: list[tuple[str, str, str]] = []  # (id, problem text, what the error line must name)

# --- every number of a single solve --------------------------------------------------------
for name in ("m", "I", "k", "rho0", "d", "g"):
    CASES += number_cases("downward", f"params.{name}", {**BAD_NUMBERS, "zero": 0, "negative": -1.0} if name != "d"
                          else {**BAD_NUMBERS, "negative": -0.01})
for name in ("z", "theta_h", "ydot", "theta_h_dot", "Kp", "Kd", "theta2_des", "theta2_dot_des", "theta_td", "energy"):
    CASES += number_cases("downward", f"fix.{name}", {"text": "high", "list": [0.4], "nan": math.nan, "1e300": 1e300})
for name in ("theta_h", "theta_h_dot", "Kp", "Kd", "theta2_des", "theta2_dot_des", "theta_td"):
    CASES += number_cases("downward", f"guess.{name}", {"map": {"v": 1}, "-inf": -math.inf, "-1e300": -1e300})
CASES += [
    ("fix.theta_h=-90 plain", dump(put(base("downward"), "fix.theta_h", -90)), "fix.theta_h"),
    ("guess.theta2_des=171 plain", dump(put(base("downward"), "guess.theta2_des", 171.4)), "guess.theta2_des"),
    ("fix.theta_td=100 deg", dump(put(base("downward"), "fix.theta_td", "100 deg")), "fix.theta_td"),
    ("fix.z=-0.1", dump(put(base("downward"), "fix.z", -0.1)), "fix.z"),
    ("fix.z=0.1 foot below ground", dump(put(base("downward"), "fix.z", 0.1)), "fix.z"),
    ("fix.ydot=1e3", dump(put(base("downward"), "fix.ydot", 1000.0)), "fix.ydot"),
    ("fix.energy below least", dump(put(base("downward"), "fix.energy", 1.0)), "fix.energy"),
    ("guess.theta_h outside bounds", dump(put(base("downward"), "guess.theta_h", "-120 deg")), "guess.theta_h"),
    ("guess.z while fixed", dump(put(base("downward"), "guess.z", 0.4)), "guess.z"),
    ("guess.energy", dump(put(base("downward"), "guess.energy", 1.0)), "guess.energy"),
    ("fix.theta_h unit furlongs", dump(put(base("downward"), "fix.theta_h", "90 furlongs")), "fix.theta_h"),
    ("fix.z unit deg", dump(put(base("downward"), "fix.z", "0.4 deg")), "fix.z"),
    ("guess.theta_h 1e999 deg", dump(put(base("downward"), "guess.theta_h", "1e999 deg")), "guess.theta_h"),
]
for label, value in {"scalar": 0.5, "one": [0.3], "three": [0, 1, 2], "reversed": [0.7, 0.3], "text": ["a", 1],
                     "nan": [math.nan, 1.0], "huge": [0.3, 1e300], "outside": [12.0, 20.0]}.items():
    CASES.append((f"bounds.z={label}", dump(put(base("downward"), "bounds.z", value)), "bounds.z"))
CASES.append(("bounds.theta_td outside", dump(put(base("downward"), "bounds.theta_td", ["87 deg", "89 deg"])), "bounds.theta_td"))
CASES.append(("bounds.speed", dump(put(base("downward"), "bounds.speed", [0, 1])), "bounds.speed"))
for label, value in {"unknown": "fastest", "list": ["min_torque"], "number": 3, "null": None}.items():
    CASES.append((f"objective={label}", dump(put(base("downward"), "objective", value)), "objective"))
for label, value in {"unknown": "sideways", "list": ["upright"], "number": 1, "null": None}.items():
    CASES.append((f"posture={label}", dump(put(base("downward"), "posture", value)), "posture"))
for label, value in {"zero": 0, "17": 17, "float": 2.5, "text": "2", "bool": True, "huge": 10**400}.items():
    CASES.append((f"strides={label}", dump(put(base("downward"), "strides", value)), "strides"))
for name, values in {
    "nodes": {"one": 1, "huge": 10**9, "float": 20.5, "text": "20"},
    "substeps": {"zero": 0, "bool": False},
    "max_iter": {"zero": 0, "negative": -5},
    "tol": {"zero": 0.0, "negative": -1e-10, "huge": 1e300, "nan": math.nan, "text": "tight"},
    "print_level": {"13": 13, "negative": -1},
    "iterations": {"any": 3},
}.items():
    CASES += number_cases("downward", f"solver.{name}", values)
for label, value in {"space": "a b", "slash": "a/b", "dots": "..", "empty": "", "long": "x" * 500,
                     "list": ["a"], "number": 5}.items():
    CASES.append((f"name={label}", dump(put(base("downward"), "name", value)), "name"))
CASES += [
    ("unknown top-level key", dump({**base("downward"), "speed": 3}), "speed"),
    ("params not a map", dump({**base("downward"), "params": [1, 2]}), "params"),
    ("fix not a map", dump({**base("downward"), "fix": "z=0.4"}), "fix"),
    ("params.mass", dump(put(base("downward"), "params.mass", 1.0)), "params.mass"),
    ("study and continuation", dump({**base("continuation_downward_speed"), "study": base("grid_downward")["study"]}),
     "continuation"),
]

# --- studies ------------------------------------------------------------------------------
SWEEP = "grid_downward"
CASES += [
    ("study not a map", dump(put(base(SWEEP), "study", "sweep")), "study"),
    ("study.kind unknown", dump(put(base(SWEEP), "study.kind", "orbit")), "study.kind"),
    ("study.kind list", dump(put(base(SWEEP), "study.kind", ["sweep"])), "study.kind"),
    ("study.kind missing", dump({**base(SWEEP), "study": {"vary": {"z": [0.3, 0.4, 0.1]}}}), "study.kind"),
    ("study.extra", dump(put(base(SWEEP), "study.extra", 1)), "study.extra"),
    ("study.vary empty", dump(put(base(SWEEP), "study.vary", {})), "study.vary"),
    ("study.vary list", dump(put(base(SWEEP), "study.vary", [1, 2, 3])), "study.vary"),
    ("study.vary three axes", dump(put(base(SWEEP), "study.vary", {"z": [0.3, 0.4, 0.1], "ydot": [0.1, 0.2, 0.1],
                                                                   "Kp": [0, 1, 1]})), "study.vary"),
    ("study.vary.speed", dump(put(base(SWEEP), "study.vary.speed", [0, 1, 0.5])), "study.vary.speed"),
    ("study.vary.energy", dump(put(base(SWEEP), "study.vary.energy", [1, 2, 1])), "study.vary.energy"),
]
for label, value in {"two": [0.1, 0.5], "reversed": [0.5, 0.1, 0.1], "zero step": [0.1, 0.5, 0],
                     "negative step": [0.1, 0.5, -0.1], "overflowing count": [0.0, 1.0, 1e-300],
                     "too many": [0.0, 1.0, 1e-6], "nan": [math.nan, 0.5, 0.1], "text": ["a", 0.5, 0.1],
                     "inf stop": [0.1, math.inf, 0.1], "huge": [0.1, 1e300, 1e299]}.items():
    CASES.append((f"study.vary.ydot={label}", dump(put(base(SWEEP), "study.vary.ydot", value)), "study.vary.ydot"))
CASES += [
    ("sweep negative z", dump(put(base(SWEEP), "study.vary.z", [-0.1, 0.5, 0.1])), "study.vary.z"),
    ("sweep z with foot below ground", dump(put(base(SWEEP), "study.vary.z", [0.1, 0.5, 0.1])), "study.vary.z"),
    ("sweep theta_td past 90 deg", dump(put(put(base(SWEEP), "study.vary", {}), "study.vary.theta_td",
                                            ["80 deg", "100 deg", "10 deg"])), "study.vary.theta_td"),
    ("sweep outside bounds", dump(put(put(base(SWEEP), "study.vary", {}), "study.vary.theta_h",
                                      ["-120 deg", "-90 deg", "10 deg"])), "study.vary.theta_h"),
    ("sweep theta_h plain degrees", dump(put(put(base(SWEEP), "study.vary", {}), "study.vary.theta_h", [-100, -80, 10])),
     "study.vary.theta_h"),
]
RANDOM = "stable_region_random"
for label, value in {"missing": "nowhere", "path": "../x", "list": ["grid"], "empty": "", "number": 3}.items():
    CASES.append((f"study.region={label}", dump(put(base(RANDOM), "study.region", value)), "study.region"))
for label, value in {"zero": 0, "negative": -1, "huge": 10**9, "float": 2.5, "text": "many"}.items():
    CASES.append((f"study.count={label}", dump(put(base(RANDOM), "study.count", value)), "study.count"))
for label, value in {"negative": -1, "huge": 2**40, "text": "x"}.items():
    CASES.append((f"study.seed={label}", dump(put(base(RANDOM), "study.seed", value)), "study.seed"))
CASES += [
    ("random source binary junk", dump(put(base(RANDOM), "study.region", "junk_region")), "study.region"),
    ("random source unfinished", dump(put(base(RANDOM), "study.region", "unfinished_region")), "study.region"),
    ("random source one axis", dump(put(base(RANDOM), "study.region", "one_axis_region")), "study.region"),
    ("random draws outside bounds", dump(put(put(base(RANDOM), "study.region", "good_region"), "bounds.z", [0.6, 0.7])),
     "study.region"),
    ("random source with no stable point", dump(put(base(RANDOM), "study.region", "unstable_region")), "study.region"),
]
TRACED = put(base(RANDOM), "study.region", "good_region")
for label, value in {"missing": "nowhere", "path": "../x", "number": 3, "junk": "junk_curves",
                     "no stability boundary": "flat_curves", "a sweep, not curves": "good_region",
                     "NaN coordinates": "nan_curves", "traced in another pair": "other_pair_curves"}.items():
    CASES.append((f"study.boundary={label}", dump(put(TRACED, "study.boundary", value)), "study.boundary"))
# Text YAML's reader refuses, and YAML 1.1 surprises.
DOWNWARD_TEXT = (ROOT / "problems" / "downward.yaml").read_text()
assert "  z: 0.4 " in DOWNWARD_TEXT
for label, char in {"NUL": "\x00", "ESC": "\x1b", "DEL": "\x7f", "U+FFFE": "\ufffe"}.items():
    CASES.append((f"YAML with {label} in a comment", DOWNWARD_TEXT + f"# note {char}\n", "malformed YAML at line"))
CASES += [
    ("fix.z sexagesimal 1:30", DOWNWARD_TEXT.replace("  z: 0.4 ", "  z: 1:30 "), "fix.z"),
    ("a 900 kB file", DOWNWARD_TEXT + "# " + "x" * 900_000 + "\n", "larger than 64 kB"),
]
BASIN = "convergence_regions"
for label, value in {"missing": "nowhere", "junk": "junk_region", "unfinished": "unfinished_region", "number": 1}.items():
    CASES.append((f"study.source={label}", dump(put(base(BASIN), "study.source", value)), "study.source"))
for label, value in {"order": {"z": [0.3, 0.4, 0.1], "ydot": [0.1, 0.2, 0.1]}, "one": {"ydot": [0.1, 0.2, 0.1]},
                     "Kp": {"ydot": [0.1, 0.2, 0.1], "Kp": [0, 1, 1]}, "list": [1, 2]}.items():
    CASES.append((f"study.grid={label}", dump(put(base(BASIN), "study.grid", value)), "study.grid"))
CASES += [
    ("study.grid.z negative", dump(put(base(BASIN), "study.grid.z", [-0.3, 0.4, 0.1])), "study.grid.z"),
    ("study.grid of 9001 x 4001 states", dump(put(base(BASIN), "study.grid", {"ydot": [0.1, 1.0, 0.0001],
                                                                             "z": [0.3, 0.7, 0.0001]})), "study.grid"),
    ("study.grid.ydot huge", dump(put(base(BASIN), "study.grid.ydot", [0.1, 1e3, 100])), "study.grid.ydot"),
    ("study.stable_at missing z", dump(put(base(BASIN), "study.stable_at", {"ydot": 0.6})), "study.stable_at"),
    ("study.stable_at extra", dump(put(base(BASIN), "study.stable_at", {"ydot": 0.6, "z": 0.4, "Kp": 1})), "study.stable_at"),
    ("study.unstable_at.z huge", dump(put(base(BASIN), "study.unstable_at.z", 1e300)), "study.unstable_at.z"),
    ("study.unstable_at.ydot nan", dump(put(base(BASIN), "study.unstable_at.ydot", math.nan)), "study.unstable_at.ydot"),
]
for label, value in {"zero": 0, "huge": 10**9, "text": "many"}.items():
    CASES.append((f"basin study.strides={label}", dump(put(base(BASIN), "study.strides", value)), "study.strides"))
for label, value in {"zero": 0, "two": 2.0, "nan": math.nan, "negative": -1e-4}.items():
    CASES.append((f"study.tolerance={label}", dump(put(base(BASIN), "study.tolerance", value)), "study.tolerance"))
ADAPTIVE = "adaptive_upright"
for key, values in {"strides": {"zero": 0, "negative": -1, "text": "x", "huge": 10**7},
                    "frozen_strides": {"zero": 0, "float": 1.5}}.items():
    for label, value in values.items():
        CASES.append((f"adaptive study.{key}={label}", dump(put(base(ADAPTIVE), f"study.{key}", value)), f"study.{key}"))
CASES.append(("adaptive study.vary", dump(put(base(ADAPTIVE), "study.vary", {"z": [0.3, 0.4, 0.1]})), "study.vary"))
for key, value, names in [
    ("perturbation", {"speed": 0.1}, "study.perturbation.speed"),
    ("perturbation", {"z": 1e300}, "study.perturbation.z"),
    ("perturbation", [0.1], "study.perturbation"),
    ("criterion", "greedy", "study.criterion"),
    ("criterion", ["thesis"], "study.criterion"),
    ("probe_strides", 0, "study.probe_strides"),
]:
    CASES.append((f"adaptive study.{key}={value!r}", dump(put(base(ADAPTIVE), f"study.{key}", value)), names))
OPTIMAL = "optimal_upright"
for key, value, names in [
    ("starts", 0, "study.starts"), ("starts", "many", "study.starts"), ("iterations", 0, "study.iterations"),
    ("seed", -3, "study.seed"), ("vary", {"z": [-0.3, 0.4, 0.1]}, "study.vary.z"),
    ("vary", {"theta_h": [60, 120, 10]}, "study.vary.theta_h"), ("count", 3, "study.count"),
    ("vary", {"Kp": [-1, 1, 0.5]}, "study.vary.Kp"), ("vary", {"z": [0.4, 0.5, 0.1], "Kd": [0.1, 0.2, 0.1]}, "study.vary.Kd"),
]:
    CASES.append((f"optimal study.{key}={value!r}", dump(put(base(OPTIMAL), f"study.{key}", value)), names))
CASES.append(("optimal study.method=newton", dump(put(base(OPTIMAL), "study.method", "newton")), "study.method"))
CASES.append(("optimal schur_nlp study with iterations",
              dump(put(put(base("optimal_upright_schur"), "study.method", "schur_nlp"), "study.iterations", 50)),
              "study.iterations"))
CASES.append(("objective least_spectral_radius with strides 2",
              dump({**base("downward"), "objective": "least_spectral_radius", "strides": 2}), "objective"))
CONTROLS = "controllers_upright"
for key, value, names in [
    ("perturbation", {}, "study.perturbation"), ("perturbation", {"z": 0}, "study.perturbation.z"),
    ("perturbation", {"z": -0.1}, "study.perturbation.z"), ("perturbation", {"Kp": 1.0}, "study.perturbation.Kp"),
    ("samples", 0, "study.samples"), ("strides", 0, "study.strides"), ("tolerance", 0, "study.tolerance"),
    ("criterion", "best", "study.criterion"), ("lqr_scale", {"z": math.inf}, "study.lqr_scale.z"),
    ("lqr_scale", "z", "study.lqr_scale"), ("lqr_scale", {"z": 1e-300}, "study.lqr_scale.z"),
    ("lqr_scale", {"theta_h": 1e-200}, "study.lqr_scale.theta_h"), ("perturbation", {"z": 1e-200}, "study.perturbation.z"),
]:
    CASES.append((f"controllers study.{key}={value!r}", dump(put(base(CONTROLS), f"study.{key}", value)), names))
CASES.append(("controllers study without perturbation",
              dump({**base(CONTROLS), "study": {"kind": "controllers"}}), "study.perturbation"))

# --- continuation -------------------------------------------------------------------------
BRANCH = "continuation_downward_speed"
for label, value in {"unknown": "speed", "list": ["ydot"], "null": None, "not fixed": "theta_h"}.items():
    CASES.append((f"continuation.parameter={label}", dump(put(base(BRANCH), "continuation.parameter", value)),
                  "continuation.parameter"))
for label, value in {"one": [0.1], "reversed": [1.5, 0.05], "text": ["slow", 1.0], "nan": [math.nan, 1.0],
                     "huge": [0.1, 1e300], "start outside": [0.6, 0.9], "scalar": 1.0}.items():
    CASES.append((f"continuation.range={label}", dump(put(base(BRANCH), "continuation.range", value)), "continuation.range"))
for key, values in {
    "step": {"zero": 0, "negative": -0.05, "huge": 1e300, "text": "small"},
    "max_points": {"one": 1, "huge": 10**6, "float": 2.5},
    "direction": {"zero": 0, "two": 2, "text": "up", "bool": True},
    "plot": {"energy": "energy", "unknown": "speed"},
    "switch": {"fold": "fold", "number": 1},
    "extra": {"any": 1},
}.items():
    for label, value in values.items():
        CASES.append((f"continuation.{key}={label}", dump(put(base(BRANCH), f"continuation.{key}", value)),
                      f"continuation.{key}"))
CURVE = "curve_slip_band"
for key, values in {
    "second": {"unknown": "speed", "same as first": "theta_td", "not fixed": "z", "list": ["energy"]},
    "second_range": {"one": [1500.0], "reversed": [2000.0, 1500.0], "text": ["low", 2000.0],
                     "start outside": [1900.0, 2000.0], "huge": [1500.0, 1e300]},
    "follow": {"unknown": "hopf", "empty": [], "twice": ["fold", "fold"], "number": 3},
    "starts": {"some": "some", "number": 1},
}.items():
    for label, value in values.items():
        CASES.append((f"continuation.{key}={label}", dump(put(base(CURVE), f"continuation.{key}", value)),
                      f"continuation.{key}"))
for missing in ("second", "second_range", "follow"):
    data = base(CURVE)
    del data["continuation"][missing]
    CASES.append((f"continuation without {missing}", dump(data), f"continuation.{missing}"))
CASES += [
    ("continuation switches and follows", dump(put(base(CURVE), "continuation.switch", "period_doubling")),
     "continuation.switch"),
    ("continuation not a map", dump(put(base(BRANCH), "continuation", "ydot")), "continuation"),
    ("continuation of k outside range", dump(put(put(base(BRANCH), "continuation.parameter", "k"),
                                                 "continuation.range", [2000, 3000])), "continuation.range"),
    ("continuation of negative m", dump(put(put(base(BRANCH), "continuation.parameter", "m"),
                                            "continuation.range", [-1, 2])), "continuation.range"),
]

# --- the newer study kinds, as hardened as the problem file --------------------------------
#: Values no whole-number study key may take.
BAD_COUNTS = {"negative": -2, "float": 2.5, "list": [3], "map": {"n": 3}, "bool": True, "null": None, "nan": math.nan,
              "10^400": 10**400}


def study_cases(problem: str, label: str, key: str, values: dict, names: str | None = None):
    data = base(problem)
    return [(f"{label} study.{key}={name}", dump(put(data, f"study.{key}", value)), names or f"study.{key}")
            for name, value in values.items()]


CASES += study_cases(RANDOM, "random", "count", {k: v for k, v in BAD_COUNTS.items() if k not in ("negative", "float")})
CASES += study_cases(RANDOM, "random", "seed", {k: v for k, v in BAD_COUNTS.items() if k != "negative"})
CASES += study_cases(RANDOM, "random", "region", {"map": {"a": 1}, "null": None, "bool": True, "dots": ".."})
CASES += study_cases(RANDOM, "random", "extra", {"any": 1})
CASES += study_cases(BASIN, "basin", "strides", {k: v for k, v in BAD_COUNTS.items() if k != "10^400"})
CASES += study_cases(BASIN, "basin", "tolerance", {"text": "tight", "list": [1e-4], "bool": True, "null": None,
                                                   "inf": math.inf, "1e300": 1e300})
for axis in ("ydot", "z"):
    CASES += study_cases(BASIN, "basin", f"stable_at.{axis}", BAD_NUMBERS)
    CASES += study_cases(BASIN, "basin", f"grid.{axis}", {"scalar": 0.5, "two": [0.1, 1.0], "reversed": [1.0, 0.1, 0.1],
                                                          "zero step": [0.1, 1.0, 0.0], "negative step": [0.1, 1.0, -0.1],
                                                          "text": [0.1, "x", 0.1], "nan": [math.nan, 1.0, 0.1]})
CASES += study_cases(BASIN, "basin", "unstable_at.z", {"text": "high", "list": [0.5], "-inf": -math.inf, "null": None})
CASES += study_cases(BASIN, "basin", "source", {"map": {"a": 1}, "null": None, "path": "../x", "empty": ""})
CASES += study_cases(BASIN, "basin", "extra", {"any": 1})
CASES += study_cases(ADAPTIVE, "adaptive", "strides", {"float": 2.5, "list": [3], "bool": True, "null": None})
CASES += study_cases(ADAPTIVE, "adaptive", "frozen_strides", {"negative": -1, "text": "x", "list": [3], "null": None,
                                                              "10^400": 10**400})
CASES += study_cases(ADAPTIVE, "adaptive", "probe_strides", {"negative": -1, "text": "x", "float": 1.5, "huge": 10**9})
for axis in ("z", "theta_h", "ydot"):
    CASES += study_cases(ADAPTIVE, "adaptive", f"perturbation.{axis}", {"text": "small", "nan": math.nan,
                                                                        "inf": math.inf, "list": [0.1]})
CASES += study_cases(ADAPTIVE, "adaptive", "criterion", {"number": 1, "null": None, "empty": ""})
CASES += study_cases(ADAPTIVE, "adaptive", "extra", {"any": 1})
CASES += study_cases(OPTIMAL, "optimal", "starts", {"negative": -1, "float": 2.5, "list": [3], "null": None,
                                                    "huge": 10**9})
CASES += study_cases(OPTIMAL, "optimal", "iterations", {"negative": -1, "text": "many", "float": 2.5, "huge": 10**9})
CASES += study_cases(OPTIMAL, "optimal", "seed", {"text": "x", "float": 2.5, "huge": 2**40})
CASES += study_cases(OPTIMAL, "optimal", "vary", {"empty": {}, "list": [1, 2], "speed": {"speed": [0, 1, 0.5]},
                                                  "three": {"z": [0.3, 0.4, 0.1], "ydot": [0.1, 0.2, 0.1],
                                                            "theta_td": [0.1, 0.2, 0.1]}},
                     names="study.vary")
CASES += study_cases(OPTIMAL, "optimal", "vary.ydot", {"scalar": 0.5, "reversed": [0.7, 0.3, 0.2], "nan": [math.nan, 1, 1],
                                                       "zero step": [0.3, 0.7, 0.0]})
CASES += study_cases(OPTIMAL, "optimal", "extra", {"any": 1})
CASES += study_cases(CONTROLS, "controllers", "samples", {"negative": -1, "float": 2.5, "text": "x", "huge": 10**9})
CASES += study_cases(CONTROLS, "controllers", "strides", {"negative": -1, "float": 2.5, "text": "x", "huge": 10**9})
CASES += study_cases(CONTROLS, "controllers", "seed", {"negative": -1, "text": "x", "float": 2.5})
CASES += study_cases(CONTROLS, "controllers", "tolerance", {"negative": -1e-6, "nan": math.nan, "text": "x",
                                                            "huge": 1e300})
for axis in ("z", "theta_h", "ydot", "theta_h_dot"):
    CASES += study_cases(CONTROLS, "controllers", f"perturbation.{axis}", {"nan": math.nan, "text": "x", "inf": math.inf})
    CASES += study_cases(CONTROLS, "controllers", f"lqr_scale.{axis}", {"zero": 0, "negative": -0.1, "nan": math.nan})
CASES += study_cases(CONTROLS, "controllers", "lqr_scale", {"speed": {"speed": 1.0}}, names="study.lqr_scale.speed")
CASES += study_cases(CONTROLS, "controllers", "criterion", {"number": 2, "null": None})
CASES += study_cases(CONTROLS, "controllers", "solve_samples", {"zero": 0, "float": 2.5, "text": "x", "list": [10]})
CASES += study_cases(CONTROLS, "controllers", "solve_samples.horizon", {"zero": 0, "text": "x", "huge": 10**9})
CASES += study_cases(CONTROLS, "controllers", "solve_samples", {"batched": {"feedback": 10}},
                     names="study.solve_samples.feedback")
CASES += study_cases(CONTROLS, "controllers", "extra", {"any": 1})
# Source files that are not what a finished run writes (a directory, a FIFO, a row with a
# cell too many or too few), for a random region, a basin source and a traced boundary.
BROKEN_SOURCES = ("dir", "fifo", "wide", "short")
for broken in BROKEN_SOURCES:
    CASES.append((f"random region points.csv {broken}", dump(put(base(RANDOM), "study.region", f"{broken}_region")),
                  "study.region"))
    CASES.append((f"basin source points.csv {broken}", dump(put(base(BASIN), "study.source", f"{broken}_region")),
                  "study.source"))
    CASES.append((f"random boundary curve.csv {broken}", dump(put(TRACED, "study.boundary", f"{broken}_curves")),
                  "study.boundary"))

# --- hip laws: the law's name, and the controls, studies and options each law takes ------
CASES += number_cases("vpp", "fix.r_vpp")
CASES += [(f"hip_law={label}", dump(put(base("downward"), "hip_law", value)), "hip_law")
          for label, value in {"unknown": "spring", "number": 1, "list": ["pd"], "null": None,
                               "the description's own law": "virtual_constraint"}.items()]
CASES += [
    ("pd control under vpp", dump(put(base("vpp"), "fix.Kp", 1.0)), "fix.Kp"),
    ("pd guess under vpp", dump(put(base("vpp"), "guess.theta2_des", 3.0)), "guess.theta2_des"),
    ("vpp control under pd", dump(put(base("downward"), "guess.r_vpp", 0.02)), "guess.r_vpp"),
    ("vpp bound under pd", dump(put(base("downward"), "bounds.r_vpp", [0.0, 0.1])), "bounds.r_vpp"),
    ("pd axis in a vpp sweep", dump(put(base("vpp_sweep_thesis"), "study.vary", {"Kp": [0.0, 1.0, 0.5]})),
     "study.vary.Kp"),
    ("pivot controller under pd", dump(put(base(CONTROLS), "study.controllers", ["constant", "pivot"])),
     "study.controllers"),
    ("unknown controller", dump(put(base(CONTROLS), "study.controllers", ["constant", "mpc"])), "study.controllers"),
]

# --- the file itself ----------------------------------------------------------------------
DOWNWARD_TEXT = (ROOT / "problems" / "downward.yaml").read_text()
assert "  z: 0.4 " in DOWNWARD_TEXT
CASES += [
    ("empty file", "", "empty"),
    ("only a comment", "# nothing here\n", "empty"),
    ("only a document marker", "---\n", "empty"),
    ("only null", "~\n", "empty"),
    ("top-level list", "- z\n- ydot\n", "mapping"),
    ("top-level text", "downward\n", "mapping"),
    ("top-level number", "42\n", "mapping"),
    ("list as a key", "fix: {[z, ydot]: 0.4}\n", "fix.[z, ydot]"),
    ("map as a key", "params: {{m: 1}: 2}\n", "params.{m: 1}"),
    ("list as a top-level key", "[a, b]: 1\n", "[a, b]"),
    ("list as a study key", "study: {kind: sweep, [vary]: 1}\n", "study.[vary]"),
    ("list as a vary key", "study: {kind: sweep, vary: {[z]: [0.3, 0.4, 0.1]}}\n", "study.vary.[z]"),
    ("repeated key", "fix: {z: 0.4, z: 0.5}\n", "duplicate key 'z'"),
    ("repeated section", DOWNWARD_TEXT + "fix: {z: 0.5}\n", "duplicate key 'fix'"),
    ("alias bomb", "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
        for p, c in zip("abcdefgh", "bcdefghi")) + "name: *i\n", "expands to more than"),
    ("recursive alias", "guess: &g {theta_h: *g}\n", "alias"),
    ("nested too deeply", "fix: " + "[" * 200 + "]" * 200 + "\n", "nested"),
    ("unclosed bracket", "fix: {z: 0.4\n", "malformed YAML at line"),
    ("tab indentation", "fix:\n\tz: 0.4\n", "malformed YAML"),
    ("two documents", DOWNWARD_TEXT + "---\nname: second\n", "malformed YAML"),
    ("python tag", "name: !!python/object:os.system ls\n", "malformed YAML"),
    ("megabytes", "# " + "x" * 1_100_000 + "\n" + DOWNWARD_TEXT, "larger than"),
]


def write_region(folder: Path, name: str, complete: bool = True, two_axes: bool = True, junk: bool = False,
                 stable: bool = True) -> None:
    """A small source study for the random and basin cases: four points, stable unless not."""
    region = folder / name
    region.mkdir(parents=True)
    if junk:
        (region / "points.csv").write_bytes(b"\x00\x89PNG\r\n\xff\xfe" * 10)
    else:
        from baslip.studies.sweep import RESULT_COLUMNS

        keys = ["sweep_ydot", "sweep_z"] if two_axes else ["sweep_ydot"]
        lines = [",".join(keys + RESULT_COLUMNS)]
        for ydot in (0.4, 0.5):
            for z in (0.4, 0.45):
                row = {"z": z, "theta_h": -1.57, "ydot": ydot, "theta_h_dot": 0.16, "Kp": -0.75, "Kd": 1.5,
                       "theta2_des": -0.05, "theta2_dot_des": 1.4, "theta_td": 0.11,
                       "spectral_radius": 0.5 if stable else 1.5, "stable": "true" if stable else "false",
                       "status": "converged"}
                cells = [str(ydot), str(z)][: len(keys)] + [str(row.get(c, "")) for c in RESULT_COLUMNS]
                lines.append(",".join(cells))
        (region / "points.csv").write_text("\n".join(lines) + "\n")
    (region / "result.json").write_text(json.dumps({"complete": complete}))


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rejected")
    write_region(folder, "good_region")
    write_region(folder, "unfinished_region", complete=False)
    write_region(folder, "one_axis_region", two_axes=False)
    write_region(folder, "junk_region", junk=True)
    write_region(folder, "unstable_region", stable=False)
    write_curves(folder, "good_curves", bounding=True)
    write_curves(folder, "flat_curves", bounding=False)
    write_curves(folder, "nan_curves", bounding=True, z="nan")
    write_curves(folder, "other_pair_curves", bounding=True, traced_in=("theta_td", "energy"))
    (folder / "junk_curves").mkdir()
    (folder / "junk_curves" / "curve.csv").write_bytes(b"\x00\x89PNG\r\n\xff\xfe" * 10)
    for broken in BROKEN_SOURCES:
        write_region(folder, f"{broken}_region")
        write_curves(folder, f"{broken}_curves", bounding=True)
        for path in (folder / f"{broken}_region" / "points.csv", folder / f"{broken}_curves" / "curve.csv"):
            break_file(path, broken)
    return folder


def break_file(path: Path, how: str) -> None:
    """Put in place of the CSV file ``path`` a directory, a FIFO, or itself with one row
    a cell too wide or too short."""
    if how in ("dir", "fifo"):
        path.unlink()
        path.mkdir() if how == "dir" else os.mkfifo(path)
        return
    lines = path.read_text().splitlines()
    lines[2] = lines[2] + ",0.5" if how == "wide" else lines[2].rsplit(",", 1)[0]
    path.write_text("\n".join(lines) + "\n")


def write_curves(folder: Path, name: str, bounding: bool, z: str = "0.42",
                 traced_in: tuple[str, str] = ("z", "ydot")) -> None:
    """A small curve result for the random study's boundary: one curve across the region,
    at height ``z``, traced (says its result.json) in the parameters ``traced_in``."""
    (folder / name).mkdir()
    flag = "true" if bounding else "false"
    lines = ["curve,type,z,ydot,stability_boundary,kappa,special"]
    lines += [f"0,neimark_sacker,{z},{ydot},{flag},0.5," for ydot in (0.3, 0.5, 0.7)]
    (folder / name / "curve.csv").write_text("\n".join(lines) + "\n")
    record = {"parameter": traced_in[0], "curves": {"second": traced_in[1]}}
    (folder / name / "result.json").write_text(json.dumps(record))


def test_the_suite_is_large_and_its_cases_are_distinct():
    assert len(CASES) >= 520
    assert len({case_id for case_id, _, _ in CASES}) == len(CASES)
    assert len({text for _, text, _ in CASES}) == len(CASES)


def assert_refused(code: int, err: str, out: Path, names: str) -> None:
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: "), err[:500]
    assert names in err, err[:500]
    assert len(err) <= MAX_LINE and "Traceback" not in err
    assert not out.exists()


class SolverBuilt(BaseException):
    """Raised (past every ``except Exception``) when a run gets as far as building a
    solver, loading compiled code or starting a worker: bad input must be refused first."""


@pytest.fixture
def no_solver(monkeypatch):
    """Make building any solver, compiled library or worker an immediate failure."""
    import baslip.engine.codegen as codegen
    import baslip.studies.runner as runner

    def refuse(*args, **kwargs):
        raise SolverBuilt("a solver was built (or a worker started) before the input was refused")

    for module, name in ((codegen, "_cached"), (codegen, "compile_functions"), (runner, "_run_lanes"),
                         (runner, "run_lanes_on_dask")):
        monkeypatch.setattr(module, name, refuse)


@pytest.mark.parametrize("problem", ["downward", "grid_downward"])
def test_the_guard_stops_a_good_problem_at_its_first_solver(tmp_path, no_solver, problem):
    """The guard of the cases below works: a good gait or study gets as far as a solver."""
    with pytest.raises(SolverBuilt):
        main([str(ROOT / "problems" / f"{problem}.yaml"), "--out", str(tmp_path / "out"), "--quiet"])


@pytest.mark.parametrize("case_id, text, names", CASES, ids=[c[0] for c in CASES])
def test_a_bad_problem_is_refused_in_one_line(workspace, capsys, no_solver, case_id, text, names):
    problem = workspace / f"case_{abs(hash(case_id))}.yaml"
    problem.write_text(text)
    out = workspace / "out"
    code = main([str(problem), "--out", str(out)])
    captured = capsys.readouterr()
    assert captured.out == ""
    assert_refused(code, captured.err, out, names)


@pytest.mark.parametrize("content, names", [
    (b"\xff\xfe\x00z: 0.4\n", "not UTF-8"),
    ("fix: {z: 0.4}\n".encode("utf-16"), "not UTF-8"),
])
def test_a_file_that_is_not_text_is_refused(workspace, capsys, content, names):
    problem = workspace / "binary.yaml"
    problem.write_bytes(content)
    out = workspace / "out"
    assert_refused(main([str(problem), "--out", str(out)]), capsys.readouterr().err, out, names)


@pytest.mark.parametrize("argv, names", [
    (["--bogus"], "--bogus"),
    ([], "problem"),
    (["--out"], "--out"),
    (["two.yaml", "three.yaml"], "three.yaml"),
])
def test_bad_command_lines_are_refused_in_one_line(capsys, argv, names):
    with pytest.raises(SystemExit) as exit_info:
        main([*(["problems/downward.yaml"] if argv and argv[0] == "--bogus" else []), *argv])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and err.count("\n") == 1 and names in err


STUDY_OPTIONS = [
    (["--jobs", "0"], "--jobs"), (["--jobs", "-1"], "--jobs"), (["--jobs", "two"], "--jobs"), (["--jobs", "1.5"], "--jobs"),
    (["--jobs", "100000"], "--jobs"), (["--lanes", "0"], "--lanes"), (["--lanes", "-3"], "--lanes"),
    (["--lanes", "x"], "--lanes"), (["--lanes", "1000000"], "--lanes"), (["--format", "gif"], "--format"),
    (["--scheduler", ""], "--scheduler"), (["--scheduler", "tls://127.0.0.1:1"], "--scheduler"),
    (["--scheduler", "ucx://127.0.0.1:1"], "--scheduler"), (["--quiet", "--verbose"], "--verbose"),
    (["--jobs"], "--jobs"), (["--lanes"], "--lanes"),
]


@pytest.mark.parametrize("options, names", STUDY_OPTIONS, ids=[" ".join(o) for o, _ in STUDY_OPTIONS])
def test_bad_study_options_are_refused_before_any_solver(workspace, capsys, no_solver, options, names):
    out = workspace / "out"
    try:
        code = main([str(ROOT / "problems" / "grid_downward.yaml"), "--out", str(out), *options])
    except SystemExit as stop:
        code = stop.code
    captured = capsys.readouterr()
    assert captured.out == ""
    assert_refused(code, captured.err, out, names)


def test_a_folder_or_a_missing_path_as_the_problem_is_refused(workspace, capsys):
    out = workspace / "out"
    assert_refused(main([str(workspace), "--out", str(out)]), capsys.readouterr().err, out, str(workspace))
    assert_refused(main([str(workspace / "nope.yaml"), "--out", str(out)]), capsys.readouterr().err, out, "no such problem file")


def test_an_output_folder_under_a_file_is_refused(workspace, capsys):
    blocker = workspace / "a_file"
    blocker.write_text("")
    code = main([str(ROOT / "problems" / "downward.yaml"), "--out", str(blocker / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "output folder" in err


@pytest.mark.parametrize("case_id", ["alias bomb", "list as a key", "sweep negative z", "empty file"])
def test_the_real_command_prints_no_traceback(tmp_path, case_id):
    (text, names), = [(t, n) for c, t, n in CASES if c == case_id]
    problem = tmp_path / "bad.yaml"
    problem.write_text(text)
    proc = subprocess.run([sys.executable, "-m", "baslip.solve", str(problem), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120)
    assert_refused(proc.returncode, proc.stderr, tmp_path / "out", names)


# --- accepted -------------------------------------------------------------------------------
PLAIN = (ROOT / "problems" / "downward.yaml").read_text()
VALID_SPELLINGS = {
    "merge key": PLAIN.replace("params: {m: 1.0, I: 0.0033, k: 1000.0, rho0: 0.2, d: 0.04, g: 9.81}",
                               "params:\n  <<: {m: 2.0, I: 0.0033, k: 1000.0, rho0: 0.2, d: 0.04, g: 9.81}\n  m: 1.0"),
    "merge of a list": PLAIN.replace("params: {m: 1.0, I: 0.0033, k: 1000.0, rho0: 0.2, d: 0.04, g: 9.81}",
                                      "params:\n  <<: [{m: 1.0, I: 0.0033}, {k: 1000.0, rho0: 0.2}]\n  d: 0.04\n  g: 9.81"),
    "an anchor": PLAIN.replace("  z: 0.4          # apex height [m]", "  z: &height 0.4"),
    "windows line ends": PLAIN.replace("\n", "\r\n"),
    "document markers": "---\n" + PLAIN + "...\n",
    "numbers as strings": PLAIN.replace("  theta_h_dot: 0.16", '  theta_h_dot: "0.16"').replace(
        "tol: 1.0e-10", 'tol: "1e-10"'),
    "radians spelled out": PLAIN.replace('theta_h: "-90 deg"\n', f'theta_h: "{-math.pi / 2!r} rad"\n'),
    "flow style": "{" + ", ".join(f"{k}: {json.dumps(v)}" for k, v in yaml.safe_load(PLAIN).items()) + "}\n",
    "comments and blank lines": "# a problem\n\n" + PLAIN.replace("\n", "  # why not\n").replace(
        "[m]  # why not", "[m]"),
    "integers for floats": PLAIN.replace("k: 1000.0", "k: 1000").replace("m: 1.0", "m: 1"),
    "open bounds": PLAIN.replace('theta_h: ["-100 deg", "-80 deg"]', 'theta_h: ["-100 deg", "-80 deg"]\n  z: [null, null]'),
}


@pytest.mark.parametrize("spelling", sorted(VALID_SPELLINGS))
def test_unusual_but_valid_spellings_mean_the_same_problem(tmp_path, spelling):
    plain, unusual = tmp_path / "downward.yaml", tmp_path / "unusual" / "downward.yaml"
    unusual.parent.mkdir()
    plain.write_text(PLAIN)
    unusual.write_text(VALID_SPELLINGS[spelling], newline="")
    expected = problem_hash(load_problem(plain))
    if spelling == "open bounds":  # z gets explicit (infinite) bounds: a different, equivalent problem
        assert load_problem(unusual).bounds["z"] == (-math.inf, math.inf)
        return
    assert problem_hash(load_problem(unusual)) == expected
