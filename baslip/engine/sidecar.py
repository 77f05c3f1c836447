"""What a caller needs of a compiled library besides its functions, kept beside it in a
JSON sidecar file.

An NLP's library holds its objective and constraints, but IPOPT also needs the NLP's sizes
and the constraints' bounds. Those come from the symbolic graph the library was generated
from, which a warm process would otherwise rebuild only to read them (about a third of
a warm solve's set-up, issue 56). They are written once, as JSON beside the library
(a file named after the library, written atomically), under the library's own key: whatever changes the
library changes its file name, so facts and library cannot disagree. Missing or unreadable
facts are not an error: the caller rebuilds the graph, as on a first run.
"""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
import tempfile
from collections.abc import Sequence

from baslip.engine.codegen import OPTIMISATION, compiling, library_file


def _facts_path(library: pathlib.Path) -> pathlib.Path:
    return library.with_name(library.name + ".json")


def read_facts(name: str, names: Sequence[str], sources: Sequence[pathlib.Path], *,
               optimisation: str = OPTIMISATION, enabled: bool | str | None = None) -> dict | None:
    """The facts kept beside the library that :func:`~baslip.engine.codegen.compile_library`
    would load for these arguments; None when compiling is off or they are not there."""
    if not compiling(enabled):
        return None
    library = library_file(name, names, sources, optimisation=optimisation)
    if library is None:
        return None
    try:
        facts = json.loads(_facts_path(library).read_text())
    except (OSError, ValueError):
        return None
    return facts if isinstance(facts, dict) else None


def write_facts(name: str, names: Sequence[str], sources: Sequence[pathlib.Path], facts: dict, *,
                optimisation: str = OPTIMISATION) -> None:
    """Keep ``facts`` (plain JSON types; infinities allowed) beside the library of these
    arguments, atomically; silently nothing where the cache cannot take them."""
    library = library_file(name, names, sources, optimisation=optimisation)
    if library is None or not library.is_file():
        return
    with contextlib.suppress(OSError):
        handle, partial = tempfile.mkstemp(dir=library.parent, prefix=f".{library.stem}.", suffix=".tmp")
        try:
            with os.fdopen(handle, "w") as out:
                json.dump(facts, out)
            os.replace(partial, _facts_path(library))
        finally:
            with contextlib.suppress(OSError):
                os.unlink(partial)
