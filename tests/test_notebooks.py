"""The specification of the example notebooks in ``examples/notebooks/``.

Each notebook is stored stripped (no outputs, no execution counts, no metadata but the
kernel's name, the language's name and the cells' tags). It runs from start to end in a
fresh kernel, from an empty temporary working folder, without an error, and writes
nothing there. Its figures show: every code cell tagged ``figure`` draws a matplotlib
Figure, shown once as a PNG image; every cell tagged ``figures`` a ``Figures`` mapping, shown
as HTML with its PNG images embedded; every cell tagged ``animation`` a
``GaitAnimation``, shown as HTML with its GIF embedded (it has no PNG or GIF output of
its own). :data:`TAGGED` says how many cells of each kind every notebook has.
"""

import base64
import os
import pathlib
import re

import pytest

nbformat = pytest.importorskip("nbformat", reason="the notebook tests need nbformat: pip install -e '.[test]'")
nbclient = pytest.importorskip("nbclient", reason="the notebook tests need nbclient: pip install -e '.[test]'")
pytest.importorskip("ipykernel", reason="the notebook tests need ipykernel: pip install -e '.[test]'")

ROOT = pathlib.Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "examples" / "notebooks"

#: Each notebook and its number of cells tagged figure, figures and animation.
TAGGED = {
    "01_solve_and_inspect.ipynb": {"figure": 2, "animation": 1},
    "02_sweep_and_maps.ipynb": {"figure": 2, "figures": 1},
    "03_branch_and_curve.ipynb": {"figure": 2, "figures": 1},
    "04_human_scale.ipynb": {"figure": 2},
    "05_controllers_and_basins.ipynb": {"figure": 1, "figures": 1},
    "06_your_own_model.ipynb": {"figure": 1, "figures": 1},
}
PNG = b"\x89PNG\r\n\x1a\n"


def _shown(cell) -> list[dict]:
    """The data of a code cell's displayed outputs (display_data and execute_result)."""
    return [output["data"] for output in cell.outputs if output["output_type"] in ("display_data", "execute_result")]


def _embedded(html: str, kind: str) -> list[bytes]:
    """The images of type ``kind`` (png, gif) embedded in ``html`` as data URIs, decoded."""
    return [base64.b64decode(data) for data in re.findall(rf"data:image/{kind};base64,([A-Za-z0-9+/=]+)", html)]


def _check_figure(cell) -> None:
    images = [base64.b64decode(data["image/png"]) for data in _shown(cell) if "image/png" in data]
    assert images and all(image.startswith(PNG) for image in images), f"no PNG image from:\n{cell.source}"
    assert len(images) == 1, f"{len(images)} images (one figure shown twice?) from:\n{cell.source}"


def _check_figures(cell) -> None:
    images = [image for data in _shown(cell) for image in _embedded(data.get("text/html", ""), "png")]
    assert images and all(image.startswith(PNG) for image in images), f"no embedded PNG images from:\n{cell.source}"


def _check_animation(cell) -> None:
    gifs = [image for data in _shown(cell) for image in _embedded(data.get("text/html", ""), "gif")]
    assert gifs and all(gif.startswith(b"GIF89a") for gif in gifs), f"no embedded GIF from:\n{cell.source}"


CHECKS = {"figure": _check_figure, "figures": _check_figures, "animation": _check_animation}


def test_the_folder_holds_exactly_the_specified_notebooks():
    assert sorted(path.name for path in NOTEBOOKS.glob("*.ipynb")) == sorted(TAGGED)


@pytest.mark.parametrize("name", sorted(TAGGED))
def test_the_notebook_is_stored_stripped_and_runs_and_draws_its_figures(name, tmp_path, monkeypatch):
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    nbformat.validate(nb)
    assert set(nb.metadata) == {"kernelspec", "language_info"} and nb.metadata["language_info"] == {"name": "python"}
    assert nb.metadata["kernelspec"]["name"] == "python3"
    assert nb.cells[0].cell_type == "markdown" and nb.cells[0].source.startswith("# ")
    for cell in nb.cells:
        assert set(cell.metadata) <= {"tags"}, cell.source
        assert str(ROOT) not in cell.source
        if cell.cell_type == "code":
            assert cell.outputs == [] and cell.execution_count is None, f"outputs stored in {name}: {cell.source}"
    tagged = {tag: [c for c in nb.cells if tag in c.metadata.get("tags", [])] for tag in CHECKS}
    assert {tag: len(cells) for tag, cells in tagged.items() if cells} == TAGGED[name]

    # The kernel imports this checkout's baslip even where it is not installed, and picks
    # its own (inline) matplotlib backend, as a user's kernel does.
    monkeypatch.delenv("MPLBACKEND", raising=False)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()

    errors = [(c.source, o.get("ename"), o.get("evalue")) for c in nb.cells if c.cell_type == "code"
              for o in c.outputs if o["output_type"] == "error"]
    assert errors == []
    for tag, cells in tagged.items():
        for cell in cells:
            assert cell.cell_type == "code", cell.source
            CHECKS[tag](cell)
    assert list(tmp_path.iterdir()) == []
