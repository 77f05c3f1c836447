"""A run's figures by name, for notebooks: they show themselves, and save as files.

Drawing only: the figures come from :mod:`baslip.viz.figures`, each labelled with the
name of the file the command line writes it to (without the suffix).
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

from matplotlib.figure import Figure

from baslip.viz.backend import release
from baslip.viz.figures import PNG_DPI

#: Resolution of the figures embedded in a notebook [dots per inch].
EMBED_DPI = 90


class Figures(Mapping[str, Figure]):
    """Figures by name: ``figures["spectral_radius_map"]`` is a matplotlib Figure.

    A notebook shows all of them, each under its name (PNG images embedded in the page:
    they need no pyplot display call). :meth:`save` writes them into a folder.

    Parameters
    ----------
    figures : Sequence of matplotlib.figure.Figure
        The figures, each named by its label, or ``figure_<n>`` without one (n its position,
        from 1); a repeated name gets ``_<n>`` appended.
    """

    def __init__(self, figures: Sequence[Figure]):
        named: dict[str, Figure] = {}
        for number, figure in enumerate(figures, start=1):
            name = str(figure.get_label() or f"figure_{number}")
            while name in named:  # two figures of one name (a study's per-case figures)
                name = f"{name}_{number}"
            named[name] = figure
            release(figure)  # shown through this mapping: pyplot must not show it again
        self._figures = named

    def __getitem__(self, name: str) -> Figure:
        if name not in self._figures:
            raise KeyError(f"no figure {name!r}; the figures are {', '.join(self._figures) or 'none'}")
        return self._figures[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._figures)

    def __len__(self) -> int:
        return len(self._figures)

    def __repr__(self) -> str:
        return f"<Figures: {', '.join(self._figures) or 'none'}>"

    def _repr_html_(self) -> str:
        parts = []
        for name, figure in self._figures.items():
            buffer = io.BytesIO()
            figure.savefig(buffer, format="png", dpi=EMBED_DPI)
            encoded = base64.b64encode(buffer.getvalue()).decode("ascii")
            parts.append(f"<h4>{html.escape(name)}</h4><img src=\"data:image/png;base64,{encoded}\" "
                         f"alt=\"{html.escape(name)}\">")
        return "\n".join(parts) or "<p>no figures</p>"

    def save(self, folder: str | Path, format: str = "png") -> list[Path]:
        """Write each figure to ``folder/<name>.<format>`` (png, svg or pdf); return the paths.

        Parameters
        ----------
        folder : str or Path
            Where the files go (created if needed).
        format : str
            The files' format, as matplotlib names it.
        """
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        paths = []
        for name, figure in self._figures.items():
            path = folder / f"{name}.{format}"
            figure.savefig(path, format=format, dpi=PNG_DPI if format == "png" else None)  # as a run writes it
            paths.append(path)
        return paths
