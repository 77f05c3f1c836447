"""The package's shape: layers that import one way, no circles, short modules, two error roots.

The layers, lowest first, are listed in :data:`LAYERS`; a module may import from its own
layer and those below it, never above. Imports inside functions count too. The linter and
the type checker configured in ``pyproject.toml`` run here as well, so the test command
enforces them.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "baslip"

#: Each sub-package or top-level module and its layer (lowest first). Entry-point shims
#: (``python -m baslip.solve`` and friends) sit above the command line they call.
LAYERS = {
    "baslip.errors": 0, "baslip.version": 0, "baslip.status": 0, "baslip.children": 0, "baslip.diagnostics": 0,
    "baslip.model": 1, "baslip.numerics": 1,
    "baslip.problem": 2,
    "baslip.engine": 3,
    "baslip.viz": 4,
    "baslip.gait": 5,
    "baslip.analysis": 6,
    "baslip.files": 7,
    "baslip.studies": 8,
    "baslip.report": 9, "baslip.results": 9,
    "baslip.api": 10,
    "baslip.cli": 11,
    "baslip.solve": 12, "baslip.animate": 12, "baslip.__main__": 12, "baslip.report.__main__": 12,
    "baslip": 13,
}
MAX_LINES = 600


def module_files() -> dict[str, pathlib.Path]:
    """Every module of baslip by its dotted name (a package by its own name)."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        modules[name] = path
    return modules


def _target(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports_of(module: str, path: pathlib.Path, modules: dict) -> set[str]:
    """The baslip modules ``module`` imports anywhere in its file (functions included),
    leaving out what only type checkers read (``if TYPE_CHECKING:`` blocks)."""
    tree = ast.parse(path.read_text())
    checking_only = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
                     and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"
                     for n in ast.walk(node)}
    found = set()
    for node in ast.walk(tree):
        if id(node) in checking_only:
            continue
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _target(module, path.name == "__init__.py", node)
            names = [f"{target}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            while name not in modules and "." in name:
                name = name.rsplit(".", 1)[0]
            if name in modules and name != module:
                found.add(name)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = module_files()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def layer(module: str) -> int:
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        head = ".".join(parts[:n])
        if head in LAYERS:
            return LAYERS[head]
    raise AssertionError(f"{module} is in no layer: add its package to LAYERS")


def test_the_scan_sees_imports_inside_functions():
    graph = import_graph()
    # gait.fixedpoint draws its figures through a lazy import inside a method
    assert "baslip.viz.figures" in graph["baslip.gait.fixedpoint"]


def test_every_module_is_in_a_layer():
    for module in module_files():
        layer(module)


def test_no_import_runs_back_up_the_layers():
    upward = [f"{a} -> {b}" for a, targets in import_graph().items() for b in targets if layer(b) > layer(a)]
    assert upward == []


def test_there_is_no_import_circle():
    graph = import_graph()
    state: dict[str, int] = {}
    circles = []

    def visit(module, path):
        state[module] = 1
        for target in sorted(graph[module]):
            if state.get(target) == 1:
                circles.append(" -> ".join([*path[path.index(target):], target]))
            elif target not in state:
                visit(target, [*path, target])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert circles == []


def test_no_module_is_over_the_line_limit():
    long = {name: n for name, path in module_files().items() if (n := len(path.read_text().splitlines())) > MAX_LINES}
    assert long == {}


def test_the_model_reads_no_yaml_and_builds_no_nlp():
    for name, path in module_files().items():
        if name.startswith("baslip.model"):
            text = path.read_text()
            assert "import yaml" not in text and "nlpsol" not in text, name


def test_every_exception_derives_from_one_of_two_roots():
    from baslip.errors import InputError, RunError

    for name in module_files():
        if name.endswith("__main__"):
            continue
        module = importlib.import_module(name)
        for cls_name, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ != name or not issubclass(cls, BaseException) or cls_name.startswith("_"):
                continue
            assert issubclass(cls, (InputError, RunError)), f"{name}.{cls_name}"


def test_help_does_not_load_casadi():
    code = ("import contextlib, io, sys\nfrom baslip.cli.main import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n        main(['--help'])\n    except SystemExit:\n        pass\n"
            "print('casadi' in sys.modules, 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_the_studies_modules_do_not_load_matplotlib():
    # A study's worker processes import the module of their task function; matplotlib
    # would add a quarter of a second to each one's start (see baslip.studies).
    studies = sorted(name for name in module_files() if name.startswith("baslip.studies."))
    code = ("import importlib, sys\n"
            f"for name in {studies!r}:\n"
            "    importlib.import_module(name)\n"
            "    if 'matplotlib' in sys.modules:\n"
            "        print(name)\n"
            "        break")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert len(studies) > 10 and out == ""


def _tool(name: str) -> list[str]:
    if importlib.util.find_spec(name) is None:
        pytest.fail(f"{name} is not installed: pip install -e '.[test]'")
    return [sys.executable, "-m", name]


def test_the_linter_passes():
    result = subprocess.run([*_tool("ruff"), "check", "baslip", "tests", "benchmarks", "examples"],
                            cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-3000:]


def test_the_type_checker_passes():
    result = subprocess.run([*_tool("mypy")], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-3000:]


def test_the_documented_layout_names_every_module():
    section = (ROOT / "docs" / "development" / "layout.md").read_text()
    missing = [str(path.relative_to(ROOT)) for path in module_files().values()
               if path.name != "__init__.py" and str(path.relative_to(ROOT)) not in section]
    assert missing == []


def test_library_keys_name_the_modules_themselves():
    from baslip.engine import kernels
    from baslip.gait import shooting

    for path in [*kernels.sources(), *shooting._nlp_sources()]:
        assert path.is_file(), path
    assert pathlib.Path(kernels.__file__) in kernels.sources()


def test_the_python_examples_of_the_readme_and_the_docs_type_check(tmp_path):
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    blocks = [block for page in pages for block in re.findall(r"```python\n(.*?)```", page.read_text(), re.S)]
    assert len(blocks) >= 3
    files = []
    for k, block in enumerate(blocks):
        files.append(tmp_path / f"readme_example_{k}.py")
        files[-1].write_text(block)
    result = subprocess.run([*_tool("mypy"), "--ignore-missing-imports", "--no-error-summary", *map(str, files)],
                            cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-3000:]
