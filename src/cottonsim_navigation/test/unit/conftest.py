"""Makes the helpers at the top of the navigation unit tests (nav_synthetic_maps) importable
from every sub-folder: the test folders are not packages."""
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
