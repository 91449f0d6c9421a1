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
