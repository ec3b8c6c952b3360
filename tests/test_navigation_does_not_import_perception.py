"""House rule: the robot-side navigation stack does not import the perception package.

cottonsim_navigation runs on the robot without the perception models (torch, weights); whatever
needs both (the results page, the paper's tables) lives in cottonsim_experiments. Every Python file
of the package counts: modules, nodes/, scripts/ and tests, imports at the top or inside functions.
"""
import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
NAVIGATION = ROOT / "src" / "cottonsim_navigation"
FORBIDDEN = "cottonsim_perception"


def python_files(package_dir):
    """The package's *.py files and its extension-less executables with a Python shebang."""
    for path in sorted(package_dir.rglob("*")):
        if not path.is_file():
            continue
        if path.suffix == ".py":
            yield path
        elif not path.suffix and path.parent.name in ("nodes", "scripts"):
            with open(path, "rb") as fh:
                if b"python" in fh.readline():
                    yield path


def forbidden_imports(source, forbidden=FORBIDDEN):
    """(line, module) of every import of ``forbidden`` or one of its modules in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            modules = [node.module]
        else:
            continue
        found += [(node.lineno, m) for m in modules if m == forbidden or m.startswith(forbidden + ".")]
    return found


def offenders(package_dir):
    out = []
    for path in python_files(package_dir):
        for line, module in forbidden_imports(path.read_text(encoding="utf-8")):
            out.append(f"{path.relative_to(package_dir.parent)}:{line} imports {module}")
    return out


def test_navigation_does_not_import_perception():
    assert list(python_files(NAVIGATION)), "no Python file found under src/cottonsim_navigation"
    found = offenders(NAVIGATION)
    assert not found, "cottonsim_navigation must not import cottonsim_perception:\n" + "\n".join(found)


def test_navigation_does_not_declare_perception():
    assert f"<exec_depend>{FORBIDDEN}</exec_depend>" not in (NAVIGATION / "package.xml").read_text()


@pytest.mark.parametrize("line", ["import cottonsim_perception",
                                  "import os, cottonsim_perception.evaluation.paper as paper",
                                  "from cottonsim_perception.evaluation.paper import PAPER_TABLES",
                                  "def f():\n    from cottonsim_perception import nn\n"])
def test_the_rule_catches_a_perception_import(line):
    assert forbidden_imports(line)


@pytest.mark.parametrize("line", ["import cottonsim_perception_extra", "from .cottonsim_perception import x",
                                  "text = 'import cottonsim_perception'", "# from cottonsim_perception import x"])
def test_the_rule_passes_other_names(line):
    assert not forbidden_imports(line)


def test_the_rule_reads_executables_without_a_suffix(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "scripts").mkdir(parents=True)
    (pkg / "scripts" / "tool").write_text("#!/usr/bin/env python3\nfrom cottonsim_perception import x\n")
    (pkg / "scripts" / "run.sh").write_text("#!/bin/bash\necho cottonsim_perception\n")
    assert offenders(pkg) == ["pkg/scripts/tool:2 imports cottonsim_perception"]
