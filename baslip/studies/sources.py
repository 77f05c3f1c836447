"""Reading the runs a study reads: a source sweep's points, a traced boundary's curves.

Each is looked up by name in the ``sources`` folder (by default the one that holds the
study's own folder), and refused with one line naming the study key when it is missing,
still being written, unfinished or not baslip's.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
from pathlib import Path

from baslip.errors import InputError
from baslip.files.lock import busy
from baslip.files.rows import DamagedTable, read_points, regular_text
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import PD, HipLaw
from baslip.problem.study import RandomSample
from baslip.studies.boundary import boundary_segments, read_curves


class StudyInputError(InputError):
    """A study refers to something that is not there (e.g. an unfinished source study)."""


def source_points(sources: Path, name: str, key: str, law: HipLaw = PD) -> tuple[list[dict], tuple[str, str]]:
    """The rows and swept quantities of the finished two-quantity sweep ``sources/name``,
    which must have been run under ``law`` (the reading study's hip law)."""
    folder = sources / name
    path = folder / "points.csv"
    if not path.exists():
        raise StudyInputError(key, f"{path} does not exist: run the study {name!r} first")
    holder = busy(folder)
    if holder is not None:
        raise StudyInputError(key, f"the study {name!r} is still being run by {holder}; wait for it to finish")
    record = {}
    with contextlib.suppress(OSError, ValueError):
        record = json.loads(regular_text(folder / "result.json"))
    if not isinstance(record, dict) or record.get("complete") is not True:
        raise StudyInputError(key, f"the study {name!r} has not run to the end (its result.json does not say complete); rerun it first")
    source_law = recorded_law(record)
    if source_law != law.name:
        raise StudyInputError(key, f"the study {name!r} was run under hip_law {source_law}, this problem is under "
                              f"{law.name}: use a source of the same law")
    try:
        rows = read_points(path)
        names = tuple(c[len("sweep_"):] for c in rows[0] if c.startswith("sweep_")) if rows else ()
        for row in rows:
            for column in (*APEX.names, *law.controls.names, "spectral_radius", "stable", "status"):
                if column not in row:
                    raise ValueError(f"it has no column {column}")
                if column in ("stable", "status"):
                    continue
                if row[column] != "" and not isinstance(row[column], float):
                    raise ValueError(f"its column {column} holds {str(row[column])[:20]!r}")
    except UnicodeDecodeError:
        raise StudyInputError(key, f"{path} is not a points.csv written by baslip (it is not UTF-8 text)") from None
    except csv.Error:
        raise StudyInputError(key, f"{path} is not a points.csv written by baslip (it is not CSV)") from None
    except DamagedTable as err:
        raise StudyInputError(key, f"{path} is not a points.csv written by baslip ({err.why})") from None
    except ValueError as err:
        raise StudyInputError(key, f"{path} is not a points.csv written by baslip ({err})") from None
    if len(names) != 2:
        raise StudyInputError(key, f"{path} is not a sweep over two quantities")
    return rows, names


def recorded_law(record: dict) -> str:
    """The hip law a finished study recorded in its provenance (pd, the only law before
    laws were recorded, if none)."""
    with contextlib.suppress(KeyError, TypeError):
        law = record["provenance"]["problem"]["hip_law"]
        if isinstance(law, str):
            return law
    return PD.name


def traced_boundary(sources: Path, study: RandomSample, names: tuple[str, str]):
    """(curve rows, boundary segments) of the study's traced boundary, or (None, None)."""
    if study.boundary is None:
        return None, None
    folder = sources / study.boundary
    path = folder / "curve.csv"
    if not path.exists():
        raise StudyInputError("study.boundary", f"{path} does not exist: run the continuation {study.boundary!r} first")
    holder = busy(folder)
    if holder is not None:
        raise StudyInputError("study.boundary", f"{study.boundary!r} is still being run by {holder}; wait for it to finish")
    traced_in = _curve_parameters(folder)
    if traced_in is not None and set(traced_in) != set(names):
        raise StudyInputError("study.boundary", f"{study.boundary!r} traced its curves in ({', '.join(traced_in)}), "
                              f"not in this study's ({', '.join(names)})")
    try:
        rows = read_curves(path)
        missing = [n for n in (*names, "curve", "stability_boundary") if rows and n not in rows[0]]
        if missing:
            raise ValueError(f"it has no column {missing[0]}")
        for row in rows:
            for n in names:
                if not math.isfinite(row[n]):
                    raise ValueError(f"its column {n} holds {row[n]}")
    except DamagedTable as err:
        raise StudyInputError("study.boundary", f"{path} is not a curve.csv written by baslip ({err.why})") from None
    except UnicodeDecodeError:
        raise StudyInputError("study.boundary", f"{path} is not a curve.csv written by baslip (it is not UTF-8 text)") from None
    except (csv.Error, ValueError, TypeError) as err:
        raise StudyInputError("study.boundary", f"{path} is not a curve.csv written by baslip ({err})") from None
    segments = boundary_segments(rows, names)
    if not segments:
        raise StudyInputError("study.boundary", f"{path} holds no curve that bounds stable gaits in ({', '.join(names)})")
    return rows, segments


def _curve_parameters(folder: Path) -> tuple[str, str] | None:
    """The two parameters a continuation's curves were traced in, from its result.json
    (None if it records none: the columns are then checked alone)."""
    with contextlib.suppress(OSError, ValueError, AttributeError, TypeError):
        record = json.loads(regular_text(folder / "result.json"))
        first, second = record["parameter"], record["curves"]["second"]
        if isinstance(first, str) and isinstance(second, str):
            return first, second
    return None
