"""The problem files that ship with baslip: where they are, and copying them out.

In a wheel they travel as ``baslip/problems``; in a clone (an editable install) they are
the repository's ``problems/`` folder.
"""

from __future__ import annotations

import shutil
from pathlib import Path


def problems_dir() -> Path:
    """The folder of the shipped ``*.yaml`` problem files."""
    packaged = Path(__file__).resolve().parents[1] / "problems"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parents[2] / "problems"


def shipped_problems() -> list[Path]:
    """The shipped problem files, sorted by name."""
    return sorted(problems_dir().glob("*.yaml"))


def find_problem(path: Path) -> Path:
    """``path`` itself where it exists or names a folder; else the shipped problem that a
    bare name means (``downward`` or ``downward.yaml``), if there is one; else ``path``.

    A file of that name in the working folder comes first, so a user's copy of a shipped
    problem is the one read."""
    if path.exists() or path.parent != Path("."):
        return path
    name = path.name if path.suffix in (".yaml", ".yml") else f"{path.name}.yaml"
    shipped = problems_dir() / name
    return shipped if shipped.is_file() else path


def describe(path: Path) -> str:
    """What a problem file is: its opening comment on one line, or ''."""
    comment = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        comment.append(line.lstrip("# ").strip())
    return " ".join(" ".join(comment).split())


def shipped_models() -> list[Path]:
    """The model descriptions the shipped problems name (``models/*.py``), sorted."""
    return sorted((problems_dir() / "models").glob("*.py"))


def copy_problems(target: Path) -> list[Path]:
    """Copy every shipped problem, and the model files they name (into ``models/``), into
    ``target`` (created if needed), never overwriting a file already there; return the
    files copied."""
    target.mkdir(parents=True, exist_ok=True)
    (target / "models").mkdir(exist_ok=True)
    copied = []
    for path in [*shipped_problems(), *shipped_models()]:
        destination = target / path.relative_to(problems_dir())
        if not destination.exists():
            shutil.copyfile(path, destination)
            copied.append(destination)
    return copied
