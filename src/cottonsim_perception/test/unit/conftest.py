"""Fixtures shared by the perception unit tests."""
import importlib.machinery
import importlib.util
import pathlib

import pytest

SCRIPTS = pathlib.Path(__file__).resolve().parents[2] / "scripts"


@pytest.fixture
def perception_script():
    """load(name) -> the executable scripts/<name> as a module (its file has no .py suffix)."""

    def load(name):
        loader = importlib.machinery.SourceFileLoader(f"{name}_script", str(SCRIPTS / name))
        module = importlib.util.module_from_spec(importlib.util.spec_from_loader(loader.name, loader))
        loader.exec_module(module)
        return module

    return load
