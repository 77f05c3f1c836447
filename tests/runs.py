"""Test helper: run a shipped continuation problem with some of its text replaced."""

from pathlib import Path

from baslip.problem.reader import load_problem
from baslip.studies.branch import run_continuation

ROOT = Path(__file__).resolve().parents[1]


def run_problem(tmp_path: Path, name: str, jobs: int | None = None, **replacements) -> tuple[dict, Path]:
    """Run ``problems/<name>.yaml`` with each key of ``replacements`` (text that must occur)
    replaced by its value, into ``tmp_path``, on ``jobs`` worker processes; return the
    summary and the output folder."""
    text = (ROOT / "problems" / f"{name}.yaml").read_text()
    for old, new in replacements.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    out = tmp_path / name
    return run_continuation(load_problem(path), out, quiet=True, jobs=jobs), out
