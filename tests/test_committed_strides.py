"""The BA-SLIP engine, whose physics is read from the model's description, computes at
5,000 committed gaits what the engine computed when its physics was its own.

The record (``tests/data/committed_strides.csv.gz``, made by
``tests/data/record_committed_strides.py`` before the engine read the description) holds,
at gaits drawn from the six committed atlases of both hip laws, the next apex and the
Jacobians dr/dX and dr/du at the studies' tolerance (1e-10). Every one must be the same
to the bit, or within 1e-13 of its scale.
"""

import csv
import gzip

import numpy as np
import pytest
from data.record_committed_strides import RECORD, SAMPLE

from baslip import ReturnMap
from baslip.model.dynamics import APEX, PARAMS, Params
from baslip.model.hiplaw import HIP_LAWS

#: What "the same" allows where not to the bit, relative to max(1, |value|).
AGREEMENT = 1e-13


@pytest.fixture(scope="module")
def record():
    with gzip.open(RECORD, "rt", newline="") as handle:
        return list(csv.DictReader(handle))


def _vector(row, names):
    return np.array([float(row[n]) for n in names])


def test_the_record_samples_every_committed_atlas_of_both_laws(record):
    assert len(record) == sum(SAMPLE.values()) == 5000
    assert {r["study"] for r in record} == set(SAMPLE)
    assert {r["hip_law"] for r in record} == set(HIP_LAWS)


def test_every_recorded_stride_and_jacobian_is_computed_again_the_same(record):
    maps = {name: ReturnMap(law=law) for name, law in HIP_LAWS.items()}
    differences, identical = [], 0
    for row in record:
        law = HIP_LAWS[row["hip_law"]]
        X, u = _vector(row, APEX.names), _vector(row, law.controls.names)
        params = Params(**dict(zip(PARAMS.names, _vector(row, PARAMS.names))))
        engine = maps[law.name]
        apex = engine.stride(X, u, params).apex
        dX, du = engine.jacobians(X, u, params)
        ours = np.concatenate([apex, dX.ravel(), du.ravel()])
        recorded = np.concatenate([
            _vector(row, [f"next_{n}" for n in APEX.names]),
            _vector(row, [f"dX_{i}{j}" for i in range(APEX.size) for j in range(APEX.size)]),
            _vector(row, [f"du_{i}_{c}" for i in range(APEX.size) for c in law.controls.names]),
        ])
        identical += np.array_equal(ours, recorded)
        differences.append(np.max(np.abs(ours - recorded) / np.maximum(1.0, np.abs(recorded))))
    assert max(differences) <= AGREEMENT, (identical, max(differences))
