"""A problem file read from disk: its YAML data, the name it defaults to, and its path.

Shared by the BA-SLIP's reader (:mod:`baslip.problem.reader`) and the reader of described
models' problems (:mod:`baslip.problem.model_file`), so that a file is refused the same
way whichever model it names.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from baslip.errors import ProblemError
from baslip.problem.shipped import find_problem
from baslip.problem.text import UnreadableText, path_argument, read_yaml, small_file_text


def read_problem_file(path: str | Path) -> tuple[Any, str, Path]:
    """A problem file's YAML data, the name it defaults to, and its path.

    Raises
    ------
    ProblemError
        The file cannot be read, is not UTF-8, is empty or is not YAML.
    """
    path = find_problem(Path(path_argument(path, "path")))
    try:
        text = small_file_text(path)
    except UnreadableText as err:
        raise ProblemError("", f"problem file {err}") from None
    except FileNotFoundError:
        shipped = " (nor the name of a shipped problem: `baslip problems` lists them)" if path.parent == Path(".") else ""
        raise ProblemError("", f"no such problem file: {path}{shipped}") from None
    except UnicodeDecodeError:
        raise ProblemError("", f"problem file {path} is not UTF-8 text") from None
    except OSError as err:
        raise ProblemError("", f"cannot read problem file {path}: {err.strerror}") from None
    try:
        data = read_yaml(text)
    except UnreadableText as err:
        raise ProblemError("", str(err)) from None
    if data is None:
        raise ProblemError("", "the problem file is empty (it holds only comments, '---' or null)")
    return data, re.sub(r"[^A-Za-z0-9_.-]", "_", path.stem), path
