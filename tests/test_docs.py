"""The documentation: the site in ``docs/`` builds with warnings as errors, it documents
every problem-file key with its default, and its API reference shows numpy-style
docstrings for every public name on it (each parameter, field and property described)."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import os
import pathlib
import re
import subprocess
import sys

import pytest

from baslip.problem import continuation, reader, study

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PROBLEM_FILES = DOCS / "guides" / "problem-files.md"


def test_the_site_builds_with_warnings_as_errors(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # mkdocs-material's banner, not a warning of the build
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                            cwd=ROOT, capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "WARNING" not in result.stderr
    reference = (tmp_path / "site" / "reference" / "running" / "index.html").read_text()
    assert "Parameters" in reference and "problem" in reference  # the API pages are generated, not empty


def test_the_readme_is_short_with_contents_and_links_into_the_site():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 350
    assert "**Contents:**" in readme
    for link in re.findall(r"\]\((docs/[^)#]+)", readme):
        assert (ROOT / link).is_file(), link


def _table_rows(section: str) -> dict[str, list[str]]:
    """The rows of the markdown tables in ``section``, by the key in their first cell."""
    rows = {}
    for line in section.splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        match = re.fullmatch(r"`(\w+)`", cells[0]) if line.startswith("|") else None
        if match:
            rows[match.group(1)] = cells
    return rows


def _kind_section(text: str, kind: str) -> str:
    start = text.index(f"**`kind: {kind}`**")
    end = text.find("**`kind: ", start + 1)
    return text[start:end if end > 0 else text.index("## Continuation keys")]


@pytest.mark.parametrize("kind", study.KINDS)
def test_every_study_key_is_documented_with_its_default(kind):
    text = PROBLEM_FILES.read_text()
    rows = _table_rows(_kind_section(text, kind))
    documented = set(rows) | {"kind"}
    assert documented == set(study.STUDY_KEYS[kind])
    cls = study.STUDY_KINDS[study.KINDS.index(kind)]
    for field in dataclasses.fields(cls):
        if field.name in rows and isinstance(field.default, (int, float)) and not isinstance(field.default, bool):
            written = re.match(r"[-+\d.e]+", rows[field.name][2].replace(",", ""))
            assert written and float(written.group()) == field.default, (field.name, rows[field.name][2])


def test_every_continuation_and_top_level_key_is_documented():
    text = PROBLEM_FILES.read_text()
    rows = _table_rows(text[text.index("## Continuation keys"):])
    assert set(continuation.CONTINUATION_KEYS) <= set(rows)
    spec = continuation.ContinuationSpec("z", 0.0, 1.0)
    for key in ("step", "max_points"):
        assert rows[key][2] == f"{getattr(spec, key):g}"
    top = _table_rows(text[:text.index("## Study keys")])
    assert set(reader.TOP_LEVEL_KEYS) <= set(top)
    settings = reader.SolverSettings()
    for field in dataclasses.fields(settings):
        assert float(top[field.name][2]) == getattr(settings, field.name), field.name


# --- The API reference: every object a page shows, and its public members ---

def _documented_objects():
    for page in sorted((DOCS / "reference").glob("*.md")):
        for name in re.findall(r"^::: (\S+)$", page.read_text(), re.M):
            module, _, attribute = name.rpartition(".")
            yield name, getattr(importlib.import_module(module), attribute)


def _section(doc: str, *titles: str) -> str:
    pattern = rf"(?:{'|'.join(titles)})\n-+\n(.*?)(?:\n\n[A-Z][a-z]+\n-+\n|\Z)"
    match = re.search(pattern, doc, re.S)
    return match.group(1) if match else ""


def _undocumented(names, section: str) -> list[str]:
    """The names no entry line (``name : type`` or ``a, b : type``) of ``section`` lists."""
    entries = [re.split(r"\s:\s|\s:$", line.strip())[0] for line in section.splitlines()
               if line and not line[0].isspace()]
    listed = {part.strip().lstrip("*") for entry in entries for part in entry.split(",")}
    return [name for name in names if name not in listed]


def _parameters(function) -> list[str]:
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):
        return []
    return [name for name in signature.parameters if name not in ("self", "cls") and not name.startswith("_")]


def _member_gaps(qualified: str, member) -> list[str]:
    if isinstance(member, (staticmethod, classmethod)):
        member = member.__func__
    if isinstance(member, property):
        return [] if (member.fget.__doc__ or "").strip() else [f"{qualified}: a property without a docstring"]
    if not inspect.isfunction(member):
        return []
    doc = inspect.getdoc(member) or ""
    if not doc.strip():
        return [f"{qualified}: no docstring"]
    missing = _undocumented(_parameters(member), _section(doc, "Parameters"))
    return [f"{qualified}: parameters {missing} not in its Parameters section"] if missing else []


def _object_gaps(name: str, obj) -> list[str]:
    doc = inspect.getdoc(obj) or ""
    if not doc.strip():
        return [f"{name}: no docstring"]
    if not inspect.isclass(obj):
        return _member_gaps(name, obj)
    gaps = []
    if dataclasses.is_dataclass(obj):
        fields = [f.name for f in dataclasses.fields(obj) if not f.name.startswith("_")]
        missing = _undocumented(fields, _section(doc, "Attributes", "Parameters"))
    else:
        missing = _undocumented(_parameters(obj.__init__) if "__init__" in vars(obj) else [], _section(doc, "Parameters"))
    if missing:
        gaps.append(f"{name}: {missing} not in its Attributes or Parameters section")
    for key, member in vars(obj).items():
        if not key.startswith("_"):
            gaps += _member_gaps(f"{name}.{key}", member)
    return gaps


def test_every_public_name_in_the_api_reference_has_a_numpy_docstring():
    objects = list(_documented_objects())
    assert len(objects) >= 25
    gaps = [gap for name, obj in objects for gap in _object_gaps(name, obj)]
    assert gaps == []


def test_no_code_in_a_table_holds_an_escaped_pipe():
    """Issue 56: MkDocs shows ``\\|`` inside a table's code literally (``[--quiet \\| --verbose]``),
    where GitHub shows a pipe: a table's code names its alternatives in the text instead."""
    pages = [ROOT / "README.md", *DOCS.rglob("*.md")]
    for page in pages:
        for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            if line.startswith("|"):
                spans = re.findall(r"`[^`]*`", line)
                assert not any("\\|" in span for span in spans), f"{page.name}:{number}"


def test_the_guides_hopper_is_the_shipped_model_file_piece_by_piece():
    """Writing a model shows problems/models/hopper.py in pieces (``py`` blocks): each piece
    is in the file as shown, so the guide cannot drift from the model the tests run."""
    guide = (ROOT / "docs" / "guides" / "models.md").read_text()
    source = (ROOT / "problems" / "models" / "hopper.py").read_text()
    pieces = re.findall(r"```py\n(.*?)```", guide, re.S)
    assert len(pieces) >= 5
    for piece in pieces:
        assert piece.strip() in source, piece
