"""Results on disk, for Python and notebooks: ``open_results("results/grid_downward")``.

Every run writes plain files (result.json and CSV). :func:`open_results` reads a folder
back as :class:`RunResults`, which shows itself briefly (``repr``, ``_repr_html_``), gives
its tables as pandas DataFrames (``to_dataframe``) and draws its figures without writing
them (``plot``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from html import escape
from pathlib import Path

#: The table ``to_dataframe()`` gives by default, by kind of run.
DEFAULT_TABLE = {"continuation": "branch", "gait": "multipliers"}


@dataclass(frozen=True)
class RunResults:
    """The files of one run: its ``summary`` (result.json) and its CSV ``tables`` by
    name (``points``, ``branch``, ``curve``, ...)."""

    folder: Path
    summary: dict
    tables: tuple[str, ...]

    @property
    def kind(self) -> str:
        """``gait``, ``continuation``, or the study's kind (``sweep``, ``random``, ...)."""
        if "kind" in self.summary:
            return self.summary["kind"]
        return "continuation" if "branches" in self.summary else "gait"

    @property
    def name(self) -> str:
        return self.summary.get("name", self.folder.name)

    def rows(self, table: str | None = None) -> list[dict]:
        """The rows of a table, numbers as floats and flags as bools."""
        from .studies.sweep import read_points

        return read_points(self.folder / f"{table or self._default_table()}.csv")

    def to_dataframe(self, table: str | None = None):
        """A table as a pandas DataFrame (needs pandas): by default ``points`` for a study,
        ``branch`` for a continuation; ``curve`` for its bifurcation curves."""
        try:
            import pandas
        except ImportError:
            raise ImportError("to_dataframe needs pandas: pip install pandas") from None
        name = table or self._default_table()
        if name not in self.tables:
            raise KeyError(f"{self.folder} has no {name}.csv; it has {', '.join(self.tables) or 'no tables'}")
        frame = pandas.read_csv(self.folder / f"{name}.csv")
        for column in frame.columns:  # true/false with gaps (failed rows) as a nullable bool
            values = set(frame[column].dropna().astype(str).str.lower())
            if values and values <= {"true", "false"}:
                frame[column] = frame[column].map(lambda v: v if pandas.isna(v) else str(v).lower() == "true").astype("boolean")
        return frame

    def plot(self) -> list:
        """The run's figures as matplotlib Figures (nothing is written): a sweep's lines
        (one quantity) or maps (two), a random sample over its region (and traced boundary),
        convergence regions and their example runs, the most stable gaits per cell and
        their trunk motion (one stride of each simulated again), an adaptive run's states
        and controls, a controller comparison, a branch's diagram and its curves."""
        from . import plots

        before = set(plots.plt.get_fignums())
        if self.kind == "sweep":
            rows = self.rows("points")
            plots.sweep_figures(rows, self._swept(rows), None)
        elif self.kind == "basin":
            plots.basin_figures(*self._basin_inputs(), None)
        elif self.kind == "optimal":
            from .model import Params
            from .studies.optimal import best_gait_motions, best_rows

            names = self._swept(self.rows("points"))
            best = best_rows(self.rows("points"), names)
            plots.sweep_figures(best, names, None)
            params = Params(**self.summary["provenance"]["problem"]["params"])
            plots.trunk_motion_figure(best_gait_motions(best, names, params), None)
        if self.kind == "random":
            rows = self.rows("points")
            names = tuple(c[len("sweep_"):] for c in rows[0] if c.startswith("sweep_"))
            region = open_results(self.folder.parent / self.summary["region"]).rows("points")
            boundary = self.summary.get("boundary")
            curves = open_results(self.folder.parent / boundary).rows("curve") if boundary else None
            plots.random_figure(rows, region, names, None, curves)
        elif self.kind == "adaptive":
            plots.adaptive_figures(self.rows("strides"), None)
        elif self.kind == "controllers":
            plots.controllers_figure(self.rows("controllers"), self.summary["perturbation"], None)
        drawn = [plots.plt.figure(n) for n in sorted(set(plots.plt.get_fignums()) - before)]
        return drawn + self._diagrams()

    def _diagrams(self) -> list:
        from . import plots

        figures = []
        if self.kind == "continuation":
            parameter = self.summary["parameter"]
            quantity = self.summary.get("provenance", {}).get("problem", {}).get("continuation", {}).get("plot", "z")
            figures.append(plots.bifurcation_diagram(self.rows("branch"), parameter, quantity))
            if "curve" in self.tables:
                second = self.summary["curves"]["second"]
                figures.append(plots.curve_diagram(self.rows("curve"), parameter, second))
        return figures

    @staticmethod
    def _swept(rows: list[dict]) -> list[str]:
        """The quantities a table's rows were swept over (its ``sweep_`` columns)."""
        return [c[len("sweep_"):] for c in (rows[0] if rows else {}) if c.startswith("sweep_")]

    def _basin_inputs(self) -> tuple:
        """The arguments of :func:`baslip.plots.basin_figures` (without the folder), read
        back from the basin study's files and its source sweep's points."""
        import numpy as np

        from .model import APEX

        basin_rows = self.rows("basin")
        source = open_results(self.folder.parent / self.summary["source"]).rows("points")
        converged = [r for r in source if r["status"] == "converged"]
        stable = [r for r in converged if r["stable"] is True]
        unstable = [r for r in converged if r["stable"] is False]

        def at(rows: list[dict], point: dict | None) -> dict | None:
            if point is None:
                return None
            return next((r for r in rows if abs(r["ydot"] - point["ydot"]) <= 1e-12 and abs(r["z"] - point["z"]) <= 1e-12), None)

        example = at(stable, self.summary.get("example_stable_point"))
        runs = self.rows("trajectories") if "trajectories" in self.tables else []
        trajectories = {
            case: (info["outcome"], info["strides"], None,
                   np.array([[r[n] for n in APEX.names] for r in runs if r["case"] == case]))
            for case, info in self.summary.get("trajectories", {}).items()
        }
        grid = (sorted({r["sweep_ydot"] for r in basin_rows}), sorted({r["sweep_z"] for r in basin_rows}))
        return (basin_rows, stable, unstable, None if example is None else stable.index(example),
                at(unstable, self.summary.get("example_unstable_point")), trajectories, grid)

    def _default_table(self) -> str:
        wanted = DEFAULT_TABLE.get(self.kind, "points")
        return wanted if wanted in self.tables else (self.tables[0] if self.tables else wanted)

    def __repr__(self) -> str:
        facts = [self.kind]
        for key in ("points", "solved", "stable", "status", "spectral_radius"):
            if isinstance(self.summary.get(key), (int, float, str)) and not isinstance(self.summary.get(key), bool):
                facts.append(f"{key} {self.summary[key]}")
        if "curves" in self.summary:
            facts.append(f"{len(self.summary['curves']['curves'])} curves")
        return f"<RunResults {self.name}: {', '.join(facts)}; tables: {', '.join(self.tables) or 'none'}>"

    def _repr_html_(self) -> str:
        scalars = {k: v for k, v in self.summary.items() if isinstance(v, (int, float, str, bool)) and k != "name"}
        body = "".join(f"<tr><th style='text-align:left'>{escape(str(k))}</th><td>{escape(str(v))}</td></tr>"
                       for k, v in scalars.items())
        return (f"<b>{escape(self.name)}</b> ({escape(self.kind)}, {escape(str(self.folder))})<table>{body}</table>"
                f"<small>tables: {escape(', '.join(self.tables) or 'none')}</small>")


def open_results(folder: str | Path) -> RunResults:
    """The results in ``folder`` (one written by ``baslip solve``). Raises
    FileNotFoundError if it holds no result.json."""
    folder = Path(folder)
    path = folder / "result.json"
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist: run the problem first")
    tables = tuple(sorted(p.stem for p in folder.glob("*.csv")))
    return RunResults(folder, json.loads(path.read_text()), tables)
