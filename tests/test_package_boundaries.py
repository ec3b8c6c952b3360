"""House rules on what each package may import.

1. The robot-side packages (navigation, perception, manipulation) run on a
   real robot without the simulator: their code (the Python package, nodes/
   and scripts/) never imports cottonsim_world, which pulls in ODE, pybullet
   and numba. Their tests may use the simulator as a fixture (a farm to map,
   a GPS model), declared as <test_depend>.
2. Every package.xml declares each cottonsim_* package its files import:
   <depend> or <exec_depend> for the package's own code, also <test_depend>
   for files under test/.

Imports are read with ``ast`` (function-level imports included), so a
mention in a docstring or comment does not count.
"""
import ast
import pathlib
import xml.etree.ElementTree as ET

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
ROBOT_SIDE = ("cottonsim_navigation", "cottonsim_perception", "cottonsim_manipulation")
SIMULATOR = "cottonsim_world"

# Files that still import the simulator, each with the reason and where it goes.
# Synthetic dataset generation renders the simulated farm: a simulator client that belongs beside the
# simulator, not in the robot-side package.
_DATASET_GENERATION = [
    "src/cottonsim_perception/src/cottonsim_perception/data/generate/config.py",
    "src/cottonsim_perception/src/cottonsim_perception/data/generate/det_labels.py",
    "src/cottonsim_perception/src/cottonsim_perception/data/generate/pipeline.py",
    "src/cottonsim_perception/src/cottonsim_perception/data/generate/poses.py",
    "src/cottonsim_perception/src/cottonsim_perception/data/generate/randomize.py",
    "src/cottonsim_perception/src/cottonsim_perception/data/generate/seg_labels.py",
    "src/cottonsim_perception/scripts/generate_dataset",
]
SIMULATOR_ALLOWED = set(_DATASET_GENERATION)
# Exempt from the package.xml check (none today).
UNDECLARED_ALLOWED: set = set()


def is_python(path: pathlib.Path) -> bool:
    if path.suffix == ".py":
        return True
    if path.suffix or not path.is_file():
        return False
    with open(path, "rb") as fh:
        first = fh.readline()
    return first.startswith(b"#!") and b"python" in first


def python_files(package_dir: pathlib.Path):
    for path in sorted(package_dir.rglob("*")):
        if "__pycache__" not in path.parts and is_python(path):
            yield path


def imported_packages(source: str) -> set:
    """Top-level names of every module the source imports (relative imports excluded)."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def declared_dependencies(package_xml: pathlib.Path) -> dict:
    """{'run': names in <depend>/<exec_depend>, 'test': those plus <test_depend>}."""
    root = ET.parse(package_xml).getroot()
    run = {e.text.strip() for tag in ("depend", "exec_depend") for e in root.iter(tag) if e.text}
    test = run | {e.text.strip() for e in root.iter("test_depend") if e.text}
    return {"run": run, "test": test}


def rel(path: pathlib.Path) -> str:
    return str(path.relative_to(ROOT))


def is_test_file(package_dir: pathlib.Path, path: pathlib.Path) -> bool:
    return path.relative_to(package_dir).parts[0] == "test"


def robot_side_code():
    for name in ROBOT_SIDE:
        package_dir = ROOT / "src" / name
        for path in python_files(package_dir):
            if not is_test_file(package_dir, path):
                yield path


def simulator_imports(path: pathlib.Path) -> bool:
    return SIMULATOR in imported_packages(path.read_text())


@pytest.mark.parametrize("path", [p for p in robot_side_code() if rel(p) not in SIMULATOR_ALLOWED], ids=rel)
def test_robot_side_code_does_not_import_the_simulator(path):
    assert not simulator_imports(path), (
        f"{rel(path)} imports {SIMULATOR}; robot-side code must run without the simulator "
        f"(shared primitives live in cottonsim_common)")


def test_the_allow_list_names_only_files_that_still_need_it():
    stale = sorted(p for p in SIMULATOR_ALLOWED if not (ROOT / p).is_file() or not simulator_imports(ROOT / p))
    assert not stale, f"remove from the allow-list (gone, or no longer importing {SIMULATOR}): {stale}"


PACKAGES = sorted(p.parent for p in ROOT.glob("src/*/package.xml"))


@pytest.mark.parametrize("package_dir", PACKAGES, ids=lambda p: p.name)
def test_package_xml_declares_every_cottonsim_package_imported(package_dir):
    deps = declared_dependencies(package_dir / "package.xml")
    missing = []
    for path in python_files(package_dir):
        if rel(path) in UNDECLARED_ALLOWED:
            continue
        kind = "test" if is_test_file(package_dir, path) else "run"
        for name in sorted(imported_packages(path.read_text())):
            if name.startswith("cottonsim_") and name != package_dir.name and name not in deps[kind]:
                missing.append(f"{rel(path)} imports {name}")
    assert not missing, (f"{package_dir.name}/package.xml lacks a dependency (<exec_depend> for code, "
                         f"<test_depend> for tests):\n  " + "\n  ".join(missing))


def test_the_import_reader_sees_nested_imports_and_ignores_text():
    source = '"""uses cottonsim_world"""\nimport os\ndef f():\n    from cottonsim_world.farm import model\n'
    assert imported_packages(source) == {"os", "cottonsim_world"}
    assert imported_packages("from . import sibling\n# import cottonsim_world\n") == set()


# Robot-side packages that still need the simulator at run time, with the reason.
# cottonsim_perception: its synthetic dataset generator renders the simulated farm (_DATASET_GENERATION).
SIMULATOR_RUN_DEPENDENCY_ALLOWED = {"cottonsim_perception"}


@pytest.mark.parametrize("package", ROBOT_SIDE)
def test_robot_side_package_xml_does_not_need_the_simulator_or_the_experiments(package):
    run = declared_dependencies(ROOT / "src" / package / "package.xml")["run"]
    forbidden = {"cottonsim_experiments"} | ({SIMULATOR} - ({SIMULATOR} if package in
                                                             SIMULATOR_RUN_DEPENDENCY_ALLOWED else set()))
    assert not run & forbidden, (f"{package}/package.xml declares {sorted(run & forbidden)} as a run dependency: "
                                 f"installing the robot stack would pull in the simulator (whole-system launch "
                                 f"files live in cottonsim_experiments; tests may <test_depend>)")
