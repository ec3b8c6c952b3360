"""Makes the helpers beside the simulator's unit tests (world_camera_poses) importable: the test
folder is not a package."""
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
