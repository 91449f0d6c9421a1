"""The top-level packages import one way: core ← datasets, renderers, reports ← pipeline."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("core", "datasets", "renderers", "reports", "pipeline")
ALLOWED = {
    "core": set(),
    "datasets": {"core"},
    "renderers": {"core"},
    "reports": {"core"},
    "pipeline": {"core", "datasets", "renderers", "reports"},
}


def imported_packages(path):
    """Top-level project packages that a source file imports (at any depth of the file)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found.update(name.split(".")[0] for name in names if name.split(".")[0] in PACKAGES)
    return found


@pytest.mark.parametrize("package", PACKAGES)
def test_package_imports_only_layers_below(package):
    offenders = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        wrong = imported_packages(path) - ALLOWED[package] - {package}
        if wrong:
            offenders[str(path.relative_to(ROOT))] = sorted(wrong)
    assert not offenders, f"{package} may import only {sorted(ALLOWED[package])}: {offenders}"


def test_the_check_sees_an_upward_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from pipeline.scene_io import build_scene\n    import reports.metrics\n")
    assert imported_packages(bad) == {"pipeline", "reports"}


def module_name(path):
    """The dotted name of a module file under :data:`ROOT` (``a/b/__init__.py`` is ``a.b``)."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package):
    """``{module: modules of package it imports}`` for every module of ``package`` (a folder under
    :data:`ROOT`), counting imports at any depth of the file: ``from a import b`` names the module
    ``a.b`` where there is one, else ``a``."""
    modules = {module_name(path): path for path in sorted((ROOT / package).rglob("*.py"))
               if "__pycache__" not in path.parts}
    graph = {}
    for module, path in modules.items():
        imported = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                imported.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                imported.update(f"{node.module}.{alias.name}" if f"{node.module}.{alias.name}" in modules
                                else node.module for alias in node.names)
        graph[module] = sorted(imported & set(modules) - {module})
    return graph


def find_cycle(graph):
    """A cycle of ``graph`` as the list of its modules (the first one repeated at the end), or ``[]``."""
    state, stack = {}, []

    def visit(module):
        state[module] = "open"
        stack.append(module)
        for other in graph.get(module, ()):
            if state.get(other) == "open":
                return stack[stack.index(other):] + [other]
            if other not in state:
                cycle = visit(other)
                if cycle:
                    return cycle
        stack.pop()
        state[module] = "done"
        return []

    for module in graph:
        if module not in state:
            cycle = visit(module)
            if cycle:
                return cycle
    return []


def test_the_pipeline_modules_import_each_other_without_a_cycle():
    graph = import_graph("pipeline")
    assert "pipeline.jobs" in graph and "pipeline.experiments.kit.model" in graph
    cycle = find_cycle(graph)
    assert not cycle, "pipeline/ imports in a circle: " + " → ".join(cycle)


def test_the_cycle_check_finds_a_circle():
    assert find_cycle({"a": ["b"], "b": ["c"], "c": ["a"], "d": ["a"]}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": ["b", "c"], "b": ["c"], "c": []}) == []


def papers_imported(graph, paper, papers):
    """The other papers' packages that modules of ``paper``'s package import (``graph``: :func:`import_graph`)."""
    own = f"pipeline.experiments.{paper}"
    return sorted({other for module, imported in graph.items() if module == own or module.startswith(own + ".")
                   for target in imported for other in papers
                   if other != paper and (target == f"pipeline.experiments.{other}"
                                          or target.startswith(f"pipeline.experiments.{other}."))})


def test_no_paper_imports_another_and_every_paper_imports_only_the_kit_of_the_experiments():
    from pipeline.experiments import PAPER_PACKAGES

    graph = import_graph("pipeline")
    for paper in PAPER_PACKAGES:
        assert papers_imported(graph, paper, PAPER_PACKAGES) == [], paper
        own = f"pipeline.experiments.{paper}"
        reaches = {target for module, imported in graph.items() if module == own or module.startswith(own + ".")
                   for target in imported if target.startswith("pipeline.")}
        assert all(t.startswith((own, "pipeline.experiments.kit")) for t in reaches), (paper, sorted(reaches))


def test_the_paper_check_sees_one_paper_importing_another():
    graph = {"pipeline.experiments.a.x": ["pipeline.experiments.kit.model", "pipeline.experiments.b.y"],
             "pipeline.experiments.b.y": ["pipeline.experiments.kit.model"]}
    assert papers_imported(graph, "a", ("a", "b")) == ["b"] and papers_imported(graph, "b", ("a", "b")) == []
