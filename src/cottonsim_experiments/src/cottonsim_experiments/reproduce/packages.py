"""Where the experiments find the other packages' files and commands, in a source or an installed workspace.

Package folders come from rospkg (``ROS_PACKAGE_PATH``, set by a workspace's setup.bash), never from
this file's place in a source tree; commands of other packages run through ``rosrun``, which finds
them in a devel space and in an install space alike. Results go where the user says
(:func:`default_results_dir`), not beside the sources.
"""
from __future__ import annotations

import os
from typing import List, Mapping, Optional

RESULTS_ENV = "COTTONSIM_RESULTS"


def package_path(package: str) -> str:
    """The folder of ROS package ``package`` (its source folder, or its share/ folder when installed)."""
    import rospkg

    try:
        return rospkg.RosPack().get_path(package)
    except rospkg.ResourceNotFound as exc:
        raise ValueError(f"ROS package {package!r} not found on ROS_PACKAGE_PATH: source the workspace's "
                         "setup.bash (devel/ or the install folder) first") from exc


def package_file(package: str, relative: str) -> str:
    """A file of ``package`` (``relative`` to its folder); ValueError naming both when it is missing."""
    path = os.path.join(package_path(package), relative)
    if not os.path.exists(path):
        raise ValueError(f"{relative!r} of package {package!r} not found (looked at {path})")
    return path


def rosrun_command(package: str, executable: str, args: List[str]) -> List[str]:
    """The command line that runs ``executable`` of ``package`` with ``args`` (a list, no shell)."""
    return ["rosrun", package, executable, *args]


def default_results_dir(environ: Optional[Mapping[str, str]] = None) -> str:
    """``$COTTONSIM_RESULTS`` when set, else ``results`` in the current directory (absolute)."""
    env = os.environ if environ is None else environ
    return os.path.abspath(env.get(RESULTS_ENV) or "results")
