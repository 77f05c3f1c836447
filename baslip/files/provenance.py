"""Where a result came from: the resolved problem, its hash, the software, the code path.

Every ``result.json`` that baslip writes carries a ``provenance`` record:

* ``problem``: the problem as baslip understood it (SI units and radians, defaults
  filled in): params, fix, guess, bounds, objective, strides, solver, study, continuation;
* ``problem_hash``: SHA-256 of that record without ``name`` and ``solver.print_level``,
  which do not change any number, and without ``hip_law`` when it is the default ``pd``
  (so results written before there were hip laws keep their hash); a resumed study must
  have the same hash;
* ``versions``: baslip, CasADi, IPOPT, NumPy and Python;
* ``code``: what each compiled library of the run actually ran on, by library name:
  ``"compiled C (<compiler version>)"`` or ``"CasADi virtual machine (<why>)"``, as
  recorded while the run loaded them (:func:`baslip.engine.codegen.recording_code`),
  in its worker processes too.
"""

from __future__ import annotations

import ctypes
import dataclasses
import glob
import hashlib
import json
import os
import sys

import casadi as ca
import numpy as np

from baslip.model.hiplaw import PD, HipLaw
from baslip.problem.reader import Problem
from baslip.version import __version__


def resolved_problem(problem: Problem) -> dict:
    """The problem as plain JSON data (tuples become lists, mappings dicts)."""
    return json.loads(json.dumps(_plain(problem)))


def _plain(value):
    if isinstance(value, HipLaw):
        return value.name
    if dataclasses.is_dataclass(value):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if hasattr(value, "items"):  # dict or MappingProxyType
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


#: Study keys added after results of their kind were committed, with their unset value:
#: left out of the hash where unset, so that those results keep their hash.
ADDED_STUDY_KEYS: dict[str, dict[str, object]] = {"atlas": {"max_spectral_radius": None, "compass_trials": 600}}


def problem_hash(problem: Problem) -> str:
    """SHA-256 (hex) of everything in the problem that can change a number."""
    record = resolved_problem(problem)
    record.pop("name")
    record["solver"].pop("print_level")
    if record.get("hip_law") == PD.name:
        record.pop("hip_law")
    if record.get("posture") == "any":  # added after results were committed: unset, left out
        record.pop("posture")
    study = record.get("study")
    if isinstance(study, dict):
        for key, unset in ADDED_STUDY_KEYS.get(str(study.get("kind")), {}).items():
            if study.get(key, unset) == unset:
                study.pop(key, None)
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()


def versions() -> dict:
    """Versions of the software that computes the results."""
    return {
        "baslip": __version__,
        "casadi": ca.__version__,  # type: ignore[attr-defined]
        "ipopt": ipopt_version(),
        "numpy": np.__version__,
        "python": sys.version.split()[0],  # platform.python_version()'s, without importing platform
    }


def ipopt_version() -> str:
    """The version of the IPOPT library that CasADi's nlpsol plugin loads."""
    for library in sorted(glob.glob(os.path.join(os.path.dirname(ca.__file__), "libipopt.*"))):
        try:
            get = ctypes.CDLL(library).GetIpoptVersion
        except (OSError, AttributeError):
            continue
        major, minor, release = ctypes.c_int(), ctypes.c_int(), ctypes.c_int()
        get(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(release))
        return f"{major.value}.{minor.value}.{release.value}"
    return "unknown"


def provenance(problem: Problem, code: dict[str, str]) -> dict:
    """The ``provenance`` record of a result of ``problem``.

    Parameters
    ----------
    problem : Problem
        The resolved problem that every part of the run solved.
    code : dict
        Library name -> what it ran on, as collected by
        :func:`baslip.engine.codegen.recording_code` around the run.
    """
    return {
        "problem": resolved_problem(problem),
        "problem_hash": problem_hash(problem),
        "versions": versions(),
        "code": dict(sorted(code.items())),
    }


def changed_entries(old: dict, new: dict, prefix: str = "") -> list[str]:
    """Dotted names of the entries that differ between two resolved problems."""
    names = []
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key), new.get(key)
        dotted = f"{prefix}{key}"
        if isinstance(a, dict) and isinstance(b, dict):
            names += changed_entries(a, b, dotted + ".")
        elif a != b:
            names.append(dotted)
    return names
