"""Record the compiled engine's strides and Jacobians at a sample of committed gaits.

The sample is 5,000 gaits drawn (seed 59) from the committed atlases of both hip laws,
at the default tolerance (1e-10) the studies used. ``tests/test_committed_strides.py``
holds the engine to this record: what the BA-SLIP engine computes must stay what it
computed when the record was made, to the bit or within 1e-13. Run from the repository's
root to make the record again (only when a stride is meant to change)::

    python tests/data/record_committed_strides.py
"""

from __future__ import annotations

import csv
import gzip
import json
import sys
from pathlib import Path

import numpy as np

from baslip import ReturnMap
from baslip.model.dynamics import APEX, PARAMS, Params
from baslip.model.hiplaw import HIP_LAWS

ROOT = Path(__file__).resolve().parents[2]
RECORD = Path(__file__).with_name("committed_strides.csv.gz")
#: Gaits drawn from each committed atlas.
SAMPLE = {"atlas_downward": 1000, "atlas_upright": 1000, "atlas_upright_capped": 1000,
          "atlas_human_pd": 200, "atlas_vpp": 1000, "atlas_vpp_human": 800}
SEED = 59
CONTROLS = tuple(dict.fromkeys(n for law in HIP_LAWS.values() for n in law.controls.names))


def columns() -> list[str]:
    """The record's columns: the gait, then the stride's next apex and Jacobians."""
    jacobian = [f"dX_{i}{j}" for i in range(APEX.size) for j in range(APEX.size)]
    by_control = [f"du_{i}_{c}" for i in range(APEX.size) for c in CONTROLS]
    return ["study", "hip_law", *PARAMS.names, *APEX.names, *CONTROLS,
            *(f"next_{n}" for n in APEX.names), *jacobian, *by_control]


def gaits(study: str, count: int, rng: np.random.Generator):
    """``count`` verified gaits of a committed atlas: (law, params, apex, controls)."""
    problem = json.loads((ROOT / "results" / study / "result.json").read_text())["provenance"]["problem"]
    law, params = HIP_LAWS[problem["hip_law"]], Params(**problem["params"])
    with open(ROOT / "results" / study / "atlas.csv", newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["status"] == "converged"]
    for i in sorted(rng.choice(len(rows), size=min(count, len(rows)), replace=False)):
        row = rows[i]
        yield (law, params, np.array([float(row[n]) for n in APEX.names]),
               np.array([float(row[n]) for n in law.controls.names]))


def record() -> int:
    """Write the record; returns the count of strides."""
    rng = np.random.default_rng(SEED)
    maps = {name: ReturnMap(law=law) for name, law in HIP_LAWS.items()}
    rows = []
    for study, count in SAMPLE.items():
        for law, params, X, u in gaits(study, count, rng):
            engine = maps[law.name]
            apex = engine.stride(X, u, params).apex
            dX, du = engine.jacobians(X, u, params)
            controls = dict(zip(law.controls.names, u))
            by_control = {(i, c): du[i, law.controls.names.index(c)]
                          for i in range(APEX.size) for c in law.controls.names}
            rows.append([study, law.name, *params.vector(), *X, *(controls.get(c, "") for c in CONTROLS),
                         *apex, *dX.ravel(), *(by_control.get((i, c), "") for i in range(APEX.size) for c in CONTROLS)])
    with gzip.open(RECORD, "wt", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns())
        writer.writerows([[repr(float(v)) if not isinstance(v, str) else v for v in row] for row in rows])
    return len(rows)


if __name__ == "__main__":
    print(f"{record()} strides recorded in {RECORD.name}", file=sys.stderr)
