"""The modules form layers: each imports only modules below it, so their imports (at the
top or inside functions) never go round in a circle."""

import ast
import graphlib
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

import mcfit

PACKAGE = Path(mcfit.__file__).parent


def _module_names():
    names = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        names[name] = path
    return names


MODULES = _module_names()


def _imported(name, path) -> set:
    """The mcfit modules that ``name`` (at ``path``) imports anywhere in its code."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = importlib.util.resolve_name("." * node.level + base, package)
            for alias in node.names:  # a submodule by name, else a name in the module
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES
                          else base)
    return {module for module in found if module in MODULES and module != name}


def import_graph() -> dict:
    return {name: _imported(name, path) for name, path in MODULES.items()}


def test_the_graph_is_read_from_the_code():
    graph = import_graph()
    assert {"mcfit.report", "mcfit.batch"} <= graph["mcfit.cli"]
    # A function-level import counts: batch imports the analysis only inside its jobs.
    assert "mcfit.analysis" in graph["mcfit.batch"]
    assert "mcfit.fit.decay_fit" in graph["mcfit.fit.power"] or \
        "mcfit.fit.power" in graph["mcfit.fit.decay_fit"]


def test_no_module_imports_itself_in_a_circle():
    try:
        tuple(graphlib.TopologicalSorter(import_graph()).static_order())
    except graphlib.CycleError as error:
        pytest.fail(f"import circle: {' -> '.join(error.args[1])}")


def test_a_circle_is_found():
    graph = import_graph()
    graph["mcfit.report"] = graph["mcfit.report"] | {"mcfit.analysis"}
    with pytest.raises(graphlib.CycleError):
        tuple(graphlib.TopologicalSorter(graph).static_order())


def _below(name, graph):
    """Every module that ``name`` imports, directly or not."""
    seen, stack = set(), [name]
    while stack:
        for module in graph[stack.pop()] - seen:
            seen.add(module)
            stack.append(module)
    return seen


@pytest.mark.parametrize("lower, upper", [
    ("mcfit.report", "mcfit.analysis"), ("mcfit.analysis", "mcfit.api"),
    ("mcfit.analysis", "mcfit.batch"), ("mcfit.model_error", "mcfit.analysis"),
    ("mcfit.batch", "mcfit.cli"),
    ("mcfit.api", "mcfit.cli")])
def test_a_layer_does_not_import_the_layers_above_it(lower, upper):
    assert upper not in _below(lower, import_graph()) | {lower}


def test_the_batch_returns_data_that_only_the_command_line_formats():
    graph = import_graph()
    assert "mcfit.report" not in graph["mcfit.batch"] | graph["mcfit.dask_jobs"]
    assert "mcfit.report" in graph["mcfit.cli"]


# The modules of the former circle, each imported first in a fresh interpreter.
@pytest.mark.parametrize("module", ["mcfit.analysis", "mcfit.api", "mcfit.batch",
                                    "mcfit.model_error", "mcfit.report", "mcfit.cli",
                                    "mcfit.dask_jobs", "mcfit.plots"])
def test_each_module_imports_first(module):
    subprocess.run([sys.executable, "-c", f"import {module}"], check=True, timeout=120,
                   env={**os.environ, "PYTHONWARNINGS": "error"})
