"""Makes the helpers beside the simulator's unit tests (world_camera_poses) importable (the test
folder is not a package), and shares the robot's URDF model between the test modules."""
import pathlib
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from cottonsim_world.robot.urdf_model import UrdfModel  # noqa: E402

ROBOT_URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"


@pytest.fixture(scope="module")
def urdf():
    """The robot's URDF (cottonsim_description) as a UrdfModel."""
    return UrdfModel.from_file(ROBOT_URDF)
