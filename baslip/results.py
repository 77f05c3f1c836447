"""Results on disk, for Python and notebooks: ``open_results("results/grid_downward")``.

Every run writes plain files (result.json and CSV). :func:`open_results` reads a folder
back as :class:`RunResults`, which shows itself briefly (``repr``, ``_repr_html_``), gives
its tables as pandas DataFrames (``to_dataframe``) and draws its figures without writing
them (``plot``).
"""

from __future__ import annotations

import io
import json
from collections.abc import Mapping
from dataclasses import dataclass
from html import escape
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from baslip.errors import InputError
from baslip.files.rows import regular_text
from baslip.problem.text import path_argument
from baslip.status import Status

#: Columns of text: they stay text where every row leaves them empty (a sweep without a
#: failure has no ``reason``).
TEXT_COLUMNS = ("status", "reason", "special", "type", "descent_stop", "meaning", "kind", "outcome", "start_status",
                "neighbours", "on")

if TYPE_CHECKING:
    from baslip.viz.gallery import Figures

#: The table ``to_dataframe()`` gives by default, by kind of run.
DEFAULT_TABLE = {"continuation": "branch", "gait": "multipliers"}


@dataclass(frozen=True)
class RunResults:
    """One run's results: its ``record`` (result.json) and its CSV ``tables`` by name
    (``points``, ``branch``, ``curve``, ...).

    Read from a folder (``folder``), or held in memory (``texts``: table name -> CSV
    text) for a run that wrote nothing. ``sources`` is the folder that holds the runs this
    one read (a basin study's source sweep, a random sample's region and boundary).

    Attributes
    ----------
    folder : Path or None
        The run's folder, or None for a run held in memory.
    record : dict
        The run's ``result.json``, as plain JSON data (SI units and radians).
    tables : tuple of str
        The names of its CSV tables, without ``.csv``, sorted.
    texts : Mapping of str to str or None
        Table name -> CSV text for a run held in memory; None for one read from a folder.
    sources : Path or None
        The folder that holds the runs this one read.
    """

    folder: Path | None
    record: dict
    tables: tuple[str, ...]
    texts: Mapping[str, str] | None = None
    sources: Path | None = None

    @property
    def kind(self) -> str:
        """``gait``, ``continuation``, or the study's kind (``sweep``, ``random``, ...)."""
        if "kind" in self.record:
            return self.record["kind"]
        return "continuation" if "branches" in self.record else "gait"

    @property
    def name(self) -> str:
        """The problem's name from ``record``, else the folder's name, else ``""``."""
        return self.record.get("name", self.folder.name if self.folder else "")

    def summary(self) -> str:
        """A short account of the run, as the command line prints it."""
        return run_summary_text(self.record)

    def rows(self, table: str | None = None) -> list[dict]:
        """The rows of a table, numbers as floats and flags as bools.

        Parameters
        ----------
        table : str, optional
            The table's name (``points``, ``branch``, ...); by default the one
            :meth:`to_dataframe` gives.

        Returns
        -------
        list of dict
            One dict per row, column name -> value, SI units and radians.
        """
        from baslip.files.rows import points_from

        name = table or self._default_table()
        with self._open(name) as handle:
            return points_from(handle, self._where(name))

    def _where(self, table: str) -> str:
        """The file of ``table``, for messages."""
        return str(self.folder / f"{table}.csv") if self.folder is not None else f"{table}.csv"

    def _open(self, table: str) -> IO[str]:
        if self.texts is not None:
            if table not in self.texts:
                raise KeyError(f"{self.name} has no table {table!r}; it has {', '.join(self.tables) or 'none'}")
            return io.StringIO(self.texts[table])
        assert self.folder is not None
        return open(self.folder / f"{table}.csv", encoding="utf-8", newline="")

    def _source(self, name: str) -> RunResults:
        """A run this one read, from the ``sources`` folder."""
        if self.sources is None:
            raise FileNotFoundError(f"{self.name} does not know where its source run {name!r} is")
        return open_results(self.sources / name)

    def to_dataframe(self, table: str | None = None):
        """A table as a pandas DataFrame (needs pandas): by default ``points`` for a study,
        ``branch`` for a continuation; ``curve`` for its bifurcation curves.

        True/false columns are nullable booleans (empty in failed rows), text columns are
        text ("" where empty, even when every row is), and a study's rows are sorted by
        their swept values (then by start), not in the order its lanes finished them.

        Parameters
        ----------
        table : str, optional
            The table's name; by default ``points`` for a study, ``branch`` for a
            continuation and ``multipliers`` for a gait (else the first table).

        Returns
        -------
        pandas.DataFrame
            The table, SI units and radians.

        Raises
        ------
        KeyError
            If the run has no such table.
        ImportError
            If pandas is not installed.
        """
        try:
            import pandas
        except ImportError:
            raise ImportError("to_dataframe needs pandas: pip install pandas") from None
        name = table or self._default_table()
        if name not in self.tables:
            raise KeyError(f"{self.folder or self.name} has no {name}.csv; it has {', '.join(self.tables) or 'no tables'}")
        from baslip.files.rows import check_rows

        with self._open(name) as handle:
            check_rows(handle, self._where(name))
            handle.seek(0)
            frame = pandas.read_csv(handle)
        for column in frame.columns:
            values = set(frame[column].dropna().astype(str).str.lower())
            if values and values <= {"true", "false"}:  # with gaps (failed rows): a nullable bool
                frame[column] = frame[column].map(lambda v: v if pandas.isna(v) else str(v).lower() == "true").astype("boolean")
            elif column in TEXT_COLUMNS or frame[column].dtype == object:
                frame[column] = frame[column].astype("string").fillna("")
        keys = [c for c in frame.columns if c.startswith("sweep_")] + [c for c in ("start",) if c in frame.columns]
        if keys and name != "curve":
            frame = frame.sort_values(keys, kind="stable").reset_index(drop=True)
        return frame

    def plot(self) -> Figures:
        """The run's figures (nothing is written), by the names of the files the command
        line writes them to: a sweep's lines (one quantity) or maps (two), a random sample
        over its region (and traced boundary), convergence regions and their example runs,
        the most stable gaits per cell and their trunk motion (one stride of each simulated
        again), an adaptive run's states and controls, a controller comparison, a branch's
        diagram and its curves. A notebook shows them all
        (:class:`~baslip.viz.gallery.Figures`)."""
        from baslip.viz import figures as plots
        from baslip.viz.gallery import Figures

        before = set(plots.plt.get_fignums())
        if self.kind == "sweep":
            rows = self.rows("points")
            plots.sweep_figures(rows, self._swept(rows), None, problem=self._title())
        elif self.kind == "basin":
            plots.basin_figures(*self._basin_inputs(), None, problem=self._title())
        elif self.kind == "optimal":
            from baslip.model.dynamics import Params
            from baslip.model.hiplaw import HIP_LAWS
            from baslip.studies.optimal import best_gait_motions, best_rows
            from baslip.studies.sources import recorded_law

            names = self._swept(self.rows("points"))
            best = best_rows(self.rows("points"), names)
            plots.sweep_figures(best, names, None, problem=self._title())
            params = Params(**self.record["provenance"]["problem"]["params"])
            law = HIP_LAWS[recorded_law(self.record)]
            plots.trunk_motion_figure(best_gait_motions(best, names, params, law=law), None, problem=self._title())
        if self.kind == "random":
            rows = self.rows("points")
            pair = tuple(c[len("sweep_"):] for c in rows[0] if c.startswith("sweep_"))
            region = self._source(self.record["region"]).rows("points")
            boundary = self.record.get("boundary")
            curves = self._source(boundary).rows("curve") if boundary else None
            plots.random_figure(rows, region, pair, None, curves, problem=self._title())
        elif self.kind == "adaptive":
            from baslip.viz.adaptive import adaptive_figures

            adaptive_figures(self.rows("strides"), None, problem=self._title())
        elif self.kind in ("atlas", "families"):
            from baslip.viz.atlasmap import atlas_figure

            plot = self.record["provenance"]["problem"]["study"]["plot"]
            atlas_figure(self.rows("atlas"), list(self.record["swept"]), (plot[0], plot[1]), None, self._title())
        elif self.kind == "controllers":
            rows, boxes = self.rows("controllers"), self.record.get("boxes", [1.0])
            smallest = [r for r in rows if r.get("box", boxes[0]) == min(boxes)]
            perturbation = {n: w * min(boxes) for n, w in self.record["perturbation"].items()}
            from baslip.viz.controllersplot import basin_figure, controllers_figure

            controllers_figure(smallest, perturbation, None, problem=self._title())
            if "basins" in self.record:
                basin_figure(self.record["basins"], self._title(), None)
        drawn = [plots.plt.figure(n) for n in sorted(set(plots.plt.get_fignums()) - before)]
        return Figures(drawn + self._diagrams())

    def _title(self) -> str:
        """The title line of the run's figures: its name, hip law and body."""
        from baslip.model.dynamics import Params
        from baslip.studies.sources import recorded_law
        from baslip.viz.labels import figure_title

        params = self.record.get("provenance", {}).get("problem", {}).get("params")
        if not isinstance(params, dict):
            return self.name
        return figure_title(self.name, Params(**params), recorded_law(self.record))

    def _diagrams(self) -> list:
        from baslip.model.dynamics import Params
        from baslip.viz import branchplot
        from baslip.viz import figures as plots

        figures = []
        if self.kind == "continuation":
            parameter = self.record["parameter"]
            quantity = self.record.get("provenance", {}).get("problem", {}).get("continuation", {}).get("plot", "z")
            figures.append(branchplot.bifurcation_diagram(self.rows("branch"), parameter, quantity, problem=self._title()))
            figures[-1].set_label("diagram")  # the names of the command line's files
            if "curve" in self.tables:
                second = self.record["curves"]["second"]
                figures.append(plots.curve_diagram(self.rows("curve"), parameter, second, problem=self._title(),
                                                  params=Params(**self.record["provenance"]["problem"]["params"]),
                                                  branch=self.rows("branch")))
                figures[-1].set_label("curve")
        return figures

    @staticmethod
    def _swept(rows: list[dict]) -> list[str]:
        """The quantities a table's rows were swept over (its ``sweep_`` columns)."""
        return [c[len("sweep_"):] for c in (rows[0] if rows else {}) if c.startswith("sweep_")]

    def _basin_inputs(self) -> tuple[Any, Any, Any, Any, Any, Any, Any]:
        """The arguments of :func:`baslip.viz.figures.basin_figures` (without the folder), read
        back from the basin study's files and its source sweep's points."""
        import numpy as np

        from baslip.model.dynamics import APEX

        basin_rows = self.rows("basin")
        source = self._source(self.record["source"]).rows("points")
        converged = [r for r in source if r["status"] == Status.CONVERGED]
        stable = [r for r in converged if r["stable"] is True]
        unstable = [r for r in converged if r["stable"] is False]

        def at(rows: list[dict], point: dict | None) -> dict | None:
            if point is None:
                return None
            return next((r for r in rows if abs(r["ydot"] - point["ydot"]) <= 1e-12 and abs(r["z"] - point["z"]) <= 1e-12), None)

        example = at(stable, self.record.get("example_stable_point"))
        runs = self.rows("trajectories") if "trajectories" in self.tables else []
        trajectories = {
            case: (info["outcome"], info["strides"], None,
                   np.array([[r[n] for n in APEX.names] for r in runs if r["case"] == case]))
            for case, info in self.record.get("trajectories", {}).items()
        }
        grid = (sorted({r["sweep_ydot"] for r in basin_rows}), sorted({r["sweep_z"] for r in basin_rows}))
        return (basin_rows, stable, unstable, None if example is None else stable.index(example),
                at(unstable, self.record.get("example_unstable_point")), trajectories, grid)

    def _default_table(self) -> str:
        wanted = DEFAULT_TABLE.get(self.kind, "points")
        return wanted if wanted in self.tables else (self.tables[0] if self.tables else wanted)

    def __repr__(self) -> str:
        facts = [self.kind]
        for key in ("points", "solved", "stable", "status", "spectral_radius"):
            if isinstance(self.record.get(key), (int, float, str)) and not isinstance(self.record.get(key), bool):
                facts.append(f"{key} {self.record[key]}")
        if "curves" in self.record:
            facts.append(f"{len(self.record['curves']['curves'])} curves")
        return f"<RunResults {self.name}: {', '.join(facts)}; tables: {', '.join(self.tables) or 'none'}>"

    def _repr_html_(self) -> str:
        scalars = {k: v for k, v in self.record.items() if isinstance(v, (int, float, str, bool)) and k != "name"}
        body = "".join(f"<tr><th style='text-align:left'>{escape(str(k))}</th><td>{escape(str(v))}</td></tr>"
                       for k, v in scalars.items())
        where = f", {escape(str(self.folder))}" if self.folder else ""
        return (f"<b>{escape(self.name)}</b> ({escape(self.kind)}{where})<table>{body}</table>"
                f"<small>tables: {escape(', '.join(self.tables) or 'none')}</small>")


def open_results(folder: str | Path) -> RunResults:
    """The results in ``folder`` (one written by ``baslip solve``). Raises
    FileNotFoundError if it holds no result.json, :class:`DamagedResults` (an
    :class:`~baslip.errors.InputError` naming the file) if its result.json is not a JSON
    object, :class:`~baslip.files.rows.DamagedTable` (an ``InputError``) naming the file
    if a table has no header or is no regular file (a table with a damaged row is refused
    so when it is read), and :class:`~baslip.errors.ArgumentError` for a ``folder`` that
    is no path.

    Parameters
    ----------
    folder : str or Path
        The run's folder; its parent is taken as the folder of the runs it read.
    """
    from baslip.files.rows import check_header

    folder = Path(path_argument(folder, "folder"))
    path = folder / "result.json"
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist: run the problem first")
    tables = tuple(sorted(p.stem for p in folder.glob("*.csv")))
    for table in tables:  # a damaged row is found when its table is read (rows, to_dataframe)
        check_header(folder / f"{table}.csv")
    return RunResults(folder, result_record(path), tables, sources=folder.parent)


class DamagedResults(InputError):
    """A file of a results folder that is not what baslip wrote; ``key`` is its path."""


def result_record(path: Path) -> dict:
    """The record of the ``result.json`` at ``path``: a JSON object in a regular UTF-8 file.

    Raises
    ------
    DamagedResults
        Naming the file, for a directory or a special file in its place, text that is not
        UTF-8 or not JSON, JSON nested too deep to read, or JSON that is not an object.
    """
    try:
        record = json.loads(regular_text(path))
    except UnicodeDecodeError:
        raise DamagedResults(str(path), "not UTF-8 text (the file is damaged)") from None
    except json.JSONDecodeError as err:
        raise DamagedResults(str(path), f"not JSON ({err.msg} at line {err.lineno}); the file is damaged") from None
    except RecursionError:
        raise DamagedResults(str(path), "JSON nested too deep to read; the file is damaged") from None
    except ValueError as err:  # not a regular file: regular_text says what it is
        raise DamagedResults(str(path), str(err)) from None
    if not isinstance(record, dict):
        raise DamagedResults(str(path), f"expected a JSON object, got {type(record).__name__} (the file is damaged)")
    return record


def read_into_memory(folder: Path, sources: Path | None) -> RunResults:
    """The results in ``folder`` held in memory, so that the folder can be removed."""
    on_disk = open_results(folder)
    texts = {name: (folder / f"{name}.csv").read_text(encoding="utf-8") for name in on_disk.tables}
    return RunResults(None, on_disk.record, on_disk.tables, texts, sources)


def run_summary_text(record: dict) -> str:
    """A gait's, a study's or a continuation's result record, told in a few lines."""
    name = record.get("name", "")
    if "parameter" not in record and "kind" not in record:
        return _gait_text(record)
    if "kind" in record:
        counts = ", ".join(f"{k} {v}" for k, v in record.items() if isinstance(v, int) and not isinstance(v, bool))
        lines = [f"{name}: {record['kind']} study {'complete' if record.get('complete', True) else 'incomplete'}: {counts}"]
        lines += record.get("answer", {}).get("lines", [])  # a families study's answer, in words
        for row in record.get("not_solved", [])[:10]:
            where = ", ".join(f"{k[len('sweep_'):]} = {v:g}" for k, v in row.items() if k.startswith("sweep_"))
            lines.append(f"  no fixed point at {where}: {row['status']} ({row['reason']})")
        if len(record.get("not_solved", [])) > 10:
            lines.append(f"  ... and {len(record['not_solved']) - 10} more points without a fixed point "
                         "(see points.csv, column reason)")
        return "\n".join(lines)
    return "\n".join(_continuation_lines(record))


def _gait_text(record: dict) -> str:
    """A single gait's result.json in two lines: its status and stability, its apex and
    control (angles in degrees)."""
    from baslip.model.quantities import quantity_text

    radius, stable = record.get("spectral_radius"), record.get("stable")
    verdict = "" if radius is None else f", spectral radius {radius:.6g} ({'stable' if stable else 'unstable'})"
    residual = "" if record.get("residual") is None else f", eps {record['residual']:.1e}"
    values = {**(record.get("apex") or {}), **(record.get("control") or {})}
    return (f"{record.get('name', '')}: {record.get('status', 'unknown')}{verdict}{residual}\n  "
            + ", ".join(quantity_text(n, v, 6) for n, v in values.items()))


def _continuation_lines(record: dict) -> list[str]:
    from baslip.model.quantities import quantity_text
    from baslip.viz.labels import CODIM2_NAMES, SPECIAL_NAMES

    name, parameter, lines = record.get("name", ""), record["parameter"], []
    for b in record["branches"]:
        special = ", ".join(f"{p['type']} at {quantity_text(parameter, p[parameter])}"
                            for p in record["special_points"] if p["branch"] == b["branch"])
        origin = f", switched at the {SPECIAL_NAMES[b['switched_from']['type']]}" if b["switched_from"] else ""
        lines.append(f"{name}: branch {b['branch']} ({b['strides']}-stride orbits{origin}): "
                     f"{b['points']} verified points, stopped: {b['stop_reason']}")
        lines.append(f"  special points: {special or 'none'}")
    for f in record["failed_switches"]:
        lines.append(f"  could not switch at the {SPECIAL_NAMES[f['type']]} at {quantity_text(parameter, f[parameter])}: "
                     f"{f['reason']}")
    curves = record.get("curves")
    if curves is not None:
        second = curves["second"]
        for c in curves["curves"]:
            lines.append(f"  curve {c['curve']} ({c['type'].replace('_', ' ')}) from "
                         f"{quantity_text(parameter, c['from'][parameter])}: {c['points']} verified points, stopped: "
                         f"{c['stop_reason']}")
        for f in curves["failed_curves"]:
            lines.append(f"  no {f['type'].replace('_', ' ')} curve from {quantity_text(parameter, f[parameter])}: {f['reason']}")
        found = "; ".join(f"{CODIM2_NAMES[p['type']]} at {quantity_text(parameter, p[parameter])}, "
                          f"{quantity_text(second, p[second])}"
                          for p in curves["codimension_two_points"])
        lines.append(f"  codimension-two points: {found or 'none'}")
    return lines
