"""Fixtures of the manipulation unit tests; makes hand_built_scene beside them importable (the
test folder is not a package)."""
import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from hand_built_scene import URDF  # noqa: E402

from cottonsim_manipulation.planning.collision import ArmCollisionModel# noqa: E402
from cottonsim_manipulation.planning.robot_body import body_boxes_from_urdf  # noqa: E402


@pytest.fixture(scope="session")
def urdf_text():
    return URDF.read_text()


@pytest.fixture(scope="session")
def body(urdf_text):
    return body_boxes_from_urdf(urdf_text)


@pytest.fixture(scope="session")
def model(body):
    return ArmCollisionModel(body=body)
